"""Fig. 7.9 of Bærentzen's thesis (2002, docs/method.md): the marzipan pig under mean curvature
flow, after 0, 2, 9 and 100 applications of the smoothing tool with the whole volume as its region
(one application = one `tool.apply {"tool":"smooth","global":true,"iterations":1}`, one time step dt
= 1/6).

Writes pig_mcf_NNN.png for each checkpoint and prints, per checkpoint, the volume (vu^3), the
area (vu^2), the sphericity (1 for a sphere: the pig should approach it), the components and
the largest | |grad d| - 1 | next to the surface.

    python3 examples/fig79_pig_mcf.py --url ws://127.0.0.1:8080/ws
"""

import time

import _common


async def main(a):
    checkpoints = sorted({int(c) for c in a.checkpoints.split(",")})
    async with _common.Client.connect(a.url) as client:
        opened = await client.create_session(a.size, "pig")
        camera = _common.default_camera(opened["size"], 40)
        rows, figures, round_trips = [], [], []
        applied = 0
        for checkpoint in checkpoints:
            while applied < checkpoint:
                started = time.perf_counter()
                await client.apply("smooth", global_=True, iterations=1)
                round_trips.append((time.perf_counter() - started) * 1000)
                applied += 1
            stats = await client.stats()
            image = await client.frame(camera, a.width, a.height, "png")
            path = _common.write_frame(a.out_dir, f"pig_mcf_{checkpoint:03d}.png", image)
            figure = {
                "applications": checkpoint,
                "inside_volume": round(stats["inside_volume"], 1),
                "surface_area": round(stats["surface_area"], 1),
                "sphericity": round(_common.sphericity(stats), 4),
                "components": stats["components"],
                "gradient_error_max": round(stats["gradient_error"]["max"], 4),
                "revision": stats["revision"],
                "frame": path,
            }
            figures.append(figure)
            rows.append([checkpoint, figure["inside_volume"], figure["surface_area"], figure["sphericity"],
                         figure["components"], figure["gradient_error_max"]])
    print(f"Fig. 7.9: the pig ({a.size}^3) under mean curvature flow")
    _common.print_table(["applications", "volume vu^3", "area vu^2", "sphericity", "components",
                         "max | |grad d| - 1 |"], rows)
    mean_ms = sum(round_trips) / len(round_trips) if round_trips else 0.0
    print(f"{len(round_trips)} applications, {mean_ms:.1f} ms per application (round trip)")
    _common.print_summary({"figure": "7.9", "size": a.size, "checkpoints": figures,
                           "ms_per_application": round(mean_ms, 2)})


if __name__ == "__main__":
    p = _common.parser("Fig. 7.9: the marzipan pig under mean curvature flow", "fig79", 128)
    p.add_argument("--checkpoints", default="0,2,9,100",
                   help="applications after which to measure and render (default %(default)s)")
    _common.run(main(p.parse_args()))
