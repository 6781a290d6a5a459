"""``python -m what_if_load``: what-if clients in C for the service soak (see --help)."""

import sys

from what_if_load._load import run

if __name__ == '__main__':
    sys.exit(run(['what_if_load', *sys.argv[1:]]))
