"""Table 7.2 of Bærentzen's thesis (2002, docs/method.md) through the network: seconds per
application of the add-blob and smoothing tools for regions of interest of side 10 to 70 vu, here as
the wall-clock round trip of one `tool.apply` seen by this client (request out, engine work,
response back).

A sphere session (radius 0.35 N; N = 256 gives 89.6 vu) takes, for each side S, --reps add
blobs and then --reps smoothings of radius S / 2 (the half side of the cubic ROI) and strength 1,
centred on random points of the starting sphere's surface. It measures twice: with view "none"
(the response only) and with view "splats" (until the splat delta of the change has arrived too,
which is what a sculpting client waits for before it can draw). Writes table72_sphere.png of the
sculpted sphere at the end.

    python3 examples/table72_network.py --url ws://127.0.0.1:8080/ws
"""

import math
import random
import time

import _common

from marzipan.frames import FrameKind

# Table 7.2 of the thesis: seconds per application on an Athlon (2001), by ROI side.
REFERENCE = {
    "add_blob": {10: 0.044, 20: 0.134, 30: 0.307, 40: 0.703, 50: 0.973, 60: 1.246, 70: 1.744},
    "smooth": {10: 0.047, 20: 0.153, 30: 0.352, 40: 0.878, 50: 1.109, 60: 1.293, 70: 1.453},
}


def random_direction(rng):
    while True:
        d = [rng.gauss(0, 1) for _ in range(3)]
        n = math.sqrt(sum(c * c for c in d))
        if n > 1e-9:
            return [c / n for c in d]


async def until_delta(client, revision):
    """Takes updates until the splat delta showing `revision` (or a later one) has arrived."""
    while True:
        update = await client.next_update(timeout=60)
        if update is None:
            raise SystemExit("the connection closed while waiting for a splat delta")
        if getattr(update, "kind", None) == FrameKind.SPLATS_DELTA and update.revision >= revision:
            return


async def main(a):
    sides = [int(s) for s in a.sides.split(",")]
    rng = random.Random(a.seed)
    timings = {}  # (mode, tool, side) -> [ms]
    async with _common.Client.connect(a.url) as client:
        opened = await client.create_session(a.size, "sphere")
        centre = [(n - 1) / 2 for n in opened["size"]]
        radius = 0.35 * min(opened["size"])
        for mode in ("none", "splats"):
            if mode == "splats":
                # Notifications of the first pass wait in the queue; the full buffer follows them.
                await client.view("splats")
                while True:
                    update = await client.next_update(timeout=60)
                    if update is None:
                        raise SystemExit("the connection closed while waiting for the full splat buffer")
                    if getattr(update, "kind", None) == FrameKind.SPLATS_FULL:
                        break
            for side in sides:
                for tool in ("add_blob", "smooth"):
                    times = timings.setdefault((mode, tool, side), [])
                    for _ in range(a.reps):
                        center = [c + radius * d for c, d in zip(centre, random_direction(rng))]
                        started = time.perf_counter()
                        result = await client.apply(tool, center=center, radius=side / 2, strength=1)
                        if mode == "splats":
                            await until_delta(client, result["revision"])
                        times.append((time.perf_counter() - started) * 1000)
        await client.view("none")
        image = await client.frame(_common.default_camera(opened["size"], 40), a.width, a.height, "png")
    path = _common.write_frame(a.out_dir, "table72_sphere.png", image)

    rows, figures = [], []
    for side in sides:
        for tool in ("add_blob", "smooth"):
            plain = timings[("none", tool, side)]
            drawn = timings[("splats", tool, side)]
            reference = REFERENCE[tool].get(side)
            row = {"side": side, "tool": tool, "reps": a.reps,
                   "median_ms": round(_common.median(plain), 2), "min_ms": round(min(plain), 2),
                   "mean_ms": round(sum(plain) / len(plain), 2),
                   "with_splats_median_ms": round(_common.median(drawn), 2),
                   "reference_ms": None if reference is None else reference * 1000}
            figures.append(row)
            rows.append([f"{side}^3", tool, row["median_ms"], row["min_ms"], row["with_splats_median_ms"],
                         "-" if reference is None else f"{reference * 1000:g}",
                         "-" if reference is None else f"{reference * 1000 / row['median_ms']:.0f}x"])
    print(f"Table 7.2 through the network: a radius-{radius:g} sphere in {a.size}^3, {a.reps} applications "
          f"per tool and side, round trips in ms")
    _common.print_table(["ROI", "tool", "median", "min", "median with splat delta", "thesis (2001)",
                         "speed-up"], rows)
    _common.print_summary({"table": "7.2", "size": a.size, "radius": radius, "rows": figures, "frame": path})


if __name__ == "__main__":
    p = _common.parser("Table 7.2 through the network", "table72", 256)
    p.add_argument("--sides", default="10,20,30,40,50,60,70", help="ROI sides in vu (default %(default)s)")
    p.add_argument("--reps", type=int, default=21, help="applications per tool and side (default %(default)s)")
    p.add_argument("--seed", type=int, default=72)
    _common.run(main(p.parse_args()))
