"""Fig. 7.12 of Bærentzen's thesis (2002, docs/method.md): the marzipan pig as it is, opened with a
sphere of radius 3 (three erosions by 1 vu, then three dilations by 1 vu: removes structure thinner
than 6 vu) and closed with it (the inverse: fills gaps narrower than 6 vu; the thesis saw changes
around the eyes).

Uses `volume.morph` open / close with radius 3 (or, with --stepwise, the thesis's own three
erode-1 and three dilate-1 calls), undo between them so both start from the same pig, and
measures each result: volume, area, components, and how much of the picture changed (pixels
whose colour moved by more than 8 levels out of 255 against the original frame).

    python3 examples/fig712_open_close.py --url ws://127.0.0.1:8080/ws
"""

import _common

from marzipan.png import decode_png


def changed_fraction(a: bytes, b: bytes) -> float:
    """The fraction of pixels of two equal-sized PNG frames that differ by more than 8 levels in
    some channel."""
    wa, ha, ca, pa = decode_png(a)
    wb, hb, cb, pb = decode_png(b)
    if (wa, ha, ca) != (wb, hb, cb):
        raise ValueError("frames of different sizes")
    changed = sum(1 for i in range(0, len(pa), ca) if max(abs(pa[i + k] - pb[i + k]) for k in range(ca)) > 8)
    return changed / (wa * ha)


async def main(a):
    async with _common.Client.connect(a.url) as client:
        opened = await client.create_session(a.size, "pig")
        camera = _common.default_camera(opened["size"], 40)
        results = {}

        async def measure(name):
            stats = await client.stats()
            image = await client.frame(camera, a.width, a.height, "png")
            path = _common.write_frame(a.out_dir, f"pig_{name}.png", image)
            results[name] = (stats, image, path)

        async def morph(kind):
            first, second = ("erode", "dilate") if kind == "open" else ("dilate", "erode")
            if not a.stepwise:
                await client.morph(kind, a.radius)
                return 1
            steps = round(a.radius)
            for _ in range(steps):
                await client.morph(first, 1)
            for _ in range(steps):
                await client.morph(second, 1)
            return 2 * steps

        await measure("original")
        for kind in ("open", "close"):
            steps = await morph(kind)
            await measure(kind)
            for _ in range(steps):
                await client.undo()
            again = await client.stats()
            if again["digest"] != results["original"][0]["digest"]:
                raise SystemExit(f"undo after {kind} did not give back the original pig")

    original = results["original"][0]
    rows, figures = [], {}
    for name, (stats, image, path) in results.items():
        changed = 0.0 if name == "original" else changed_fraction(results["original"][1], image)
        figures[name] = {
            "inside_volume": round(stats["inside_volume"], 1),
            "surface_area": round(stats["surface_area"], 1),
            "components": stats["components"],
            "volume_change": round(stats["inside_volume"] - original["inside_volume"], 1),
            "area_change": round(stats["surface_area"] - original["surface_area"], 1),
            "pixels_changed": round(changed, 4),
            "digest": stats["digest"],
            "frame": path,
        }
        f = figures[name]
        rows.append([name, f["inside_volume"], f["volume_change"], f["surface_area"], f["area_change"],
                     f["components"], f"{100 * changed:.2f}%"])
    how = "3 erosions and 3 dilations by 1 vu" if a.stepwise else f"volume.morph radius {a.radius:g}"
    print(f"Fig. 7.12: the pig ({a.size}^3) opened and closed ({how})")
    _common.print_table(["pig", "volume vu^3", "change", "area vu^2", "change", "components", "pixels changed"],
                        rows)
    _common.print_summary({"figure": "7.12", "size": a.size, "radius": a.radius, "stepwise": a.stepwise,
                           **figures})


if __name__ == "__main__":
    p = _common.parser("Fig. 7.12: the pig opened and closed with a sphere of radius 3", "fig712", 128)
    p.add_argument("--radius", type=float, default=3.0, help="the sphere's radius, vu (default %(default)s)")
    p.add_argument("--stepwise", action="store_true",
                   help="erode and dilate by 1 vu radius times each, as the thesis did")
    _common.run(main(p.parse_args()))
