import sys

from rotorlab.cli import main

sys.exit(main())
