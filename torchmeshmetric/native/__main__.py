"""``python -m torchmeshmetric.native``: build every C++ extension now (as ``torchmeshmetric build``)."""

import sys

from torchmeshmetric.cli import main

if __name__ == "__main__":
    sys.exit(main(["build", *sys.argv[1:]]))
