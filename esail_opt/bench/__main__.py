"""``python -m esail_opt.bench NAME...``: the same as ``esail-opt-bench NAME...``."""

import sys

from esail_opt.bench.cli import main

if __name__ == "__main__":
    sys.exit(main())
