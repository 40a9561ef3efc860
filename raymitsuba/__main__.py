from raymitsuba.cli import main

main()
