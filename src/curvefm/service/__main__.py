"""``python -m curvefm.service [options]`` is ``curvefm serve [options]``."""

import sys

from curvefm.cli import main

if __name__ == "__main__":
    sys.exit(main(["serve", *sys.argv[1:]]))
