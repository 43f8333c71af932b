"""``python -m raytrace``: the same command line as ``raytrace``."""

import sys

from .cli import main

sys.exit(main())
