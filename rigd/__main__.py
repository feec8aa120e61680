import sys

from rigd.cli import main

if __name__ == "__main__":  # spawned worker processes import this module again: do not rerun the CLI
    sys.exit(main())
