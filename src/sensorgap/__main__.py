import sys

from sensorgap.cli import main

sys.exit(main())
