from raymitsuba.cli import run

if __name__ == "__main__":  # not in the workers a batch spawns, which import this module
    run()
