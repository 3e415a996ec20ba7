"""``python -m curvefm.workers [options]`` is ``curvefm worker [options]``."""

import sys

from curvefm.cli import main

if __name__ == "__main__":
    sys.exit(main(["worker", *sys.argv[1:]]))
