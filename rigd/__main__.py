import sys

from rigd.cli import main

sys.exit(main())
