import sys

from masspush.cli import main

sys.exit(main())
