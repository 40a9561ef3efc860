from raymitsuba.cli import run

run()
