import sys

from mimicbench.cli import main

sys.exit(main())
