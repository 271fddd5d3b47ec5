import sys

from pickdemo.cli import main

sys.exit(main())
