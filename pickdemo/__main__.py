"""`python -m pickdemo`: the command line (:mod:`pickdemo.apps.cli`)."""

import sys

from pickdemo.apps.cli import main

sys.exit(main())
