import sys

from sensorgap.entry import main

sys.exit(main())
