import sys

from pickdemo.apps.cli import main

sys.exit(main())
