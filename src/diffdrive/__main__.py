"""``python -m diffdrive``: the command line."""

import sys

from diffdrive.cli import main

sys.exit(main())
