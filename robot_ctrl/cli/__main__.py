import sys

from robot_ctrl.cli import main

sys.exit(main())
