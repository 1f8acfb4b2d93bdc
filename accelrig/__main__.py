import sys

from accelrig.cli import main

sys.exit(main())
