"""``python -m torchmeshmetric``."""

import sys

from torchmeshmetric.cli import main

sys.exit(main())
