import sys

from fitode.cli import entry

sys.exit(entry())
