import sys

from fitode.cli import main

sys.exit(main())
