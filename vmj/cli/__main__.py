"""`python -m vmj.cli`: the `vmj` command."""

import sys

from . import main

sys.exit(main())
