"""What the examples share: the command line, the connection, writing frames, tables.

Every example talks to a running server (`marzipan serve`, default ws://127.0.0.1:8080/ws or
$MARZIPAN_URL), writes its PNG frames into --out-dir, prints its figures as a table and ends
with one line of JSON holding them (what tests/protocol/python/test_examples.py reads).
Coordinates in vu of the session's grid, y up; times in milliseconds of wall clock on the
client, network round trips included.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
import sys
from pathlib import Path

# Run from a checkout without installing: the package sits next to this directory.
try:
    import marzipan  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from marzipan import Client, MarzipanError  # noqa: E402
from marzipan.cli import default_camera  # noqa: E402

DEFAULT_URL = os.environ.get("MARZIPAN_URL", "ws://127.0.0.1:8080/ws")

__all__ = ["Client", "default_camera", "parser", "run", "write_frame", "sphericity", "equivalent_radius",
           "print_table", "print_summary", "median"]


def parser(description: str, out_dir: str, size: int) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--url", default=DEFAULT_URL, help="the server's WebSocket URL (default %(default)s)")
    p.add_argument("--out-dir", default=out_dir, help="where the PNG frames go (default %(default)s)")
    p.add_argument("--size", type=int, default=size, help="grid side N of the N^3 session (default %(default)s)")
    p.add_argument("--width", type=int, default=384, help="frame width in pixels (default %(default)s)")
    p.add_argument("--height", type=int, default=384, help="frame height in pixels (default %(default)s)")
    return p


def run(main) -> None:
    """Runs the example's coroutine; a server error or a lost connection exits 1 with its message."""
    try:
        asyncio.run(main)
    except MarzipanError as e:
        print(f"{Path(sys.argv[0]).name}: {e}", file=sys.stderr)
        sys.exit(1)


def write_frame(out_dir: str, name: str, data: bytes) -> str:
    path = Path(out_dir) / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return str(path)


def sphericity(stats: dict) -> float:
    """pi^(1/3) (6 V)^(2/3) / A: 1 for a sphere, less for anything else of the same volume."""
    volume, area = stats["inside_volume"], stats["surface_area"]
    if volume <= 0 or area <= 0:
        return 0.0
    return math.pi ** (1 / 3) * (6 * volume) ** (2 / 3) / area


def equivalent_radius(stats: dict) -> float:
    """The radius of the sphere with the solid's volume, vu."""
    return (3 * max(stats["inside_volume"], 0.0) / (4 * math.pi)) ** (1 / 3)


def median(values):
    s = sorted(values)
    n = len(s)
    return (s[n // 2] + s[(n - 1) // 2]) / 2 if n else float("nan")


def print_table(headers, rows) -> None:
    """A Markdown table, columns as wide as their widest cell."""
    cells = [[str(h) for h in headers]] + [[c if isinstance(c, str) else f"{c:g}" if isinstance(c, float) else str(c)
                                           for c in row] for row in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    for n, row in enumerate(cells):
        print("| " + " | ".join(c.rjust(w) for c, w in zip(row, widths)) + " |")
        if n == 0:
            print("|" + "|".join("-" * (w + 2) for w in widths) + "|")


def print_summary(summary: dict) -> None:
    print(json.dumps(summary, separators=(",", ":")), flush=True)
