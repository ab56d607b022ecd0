"""`python3 -m marzipan batch OPS.jsonl --url ws://HOST:PORT/ws ...` (see cli.py)."""

import sys

from .cli import main

sys.exit(main())
