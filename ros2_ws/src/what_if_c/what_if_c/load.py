"""``python -m what_if_c.load``: what-if clients in C for the service soak (see --help)."""

import sys

from what_if_c._load import run

if __name__ == '__main__':
    sys.exit(run(['what_if_c.load', *sys.argv[1:]]))
