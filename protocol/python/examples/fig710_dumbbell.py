"""Fig. 7.10 of Bærentzen's thesis (2002, docs/method.md): a dumbbell (two spheres joined by a
cylinder) under mean curvature flow pinches off at the handle before the spheres vanish. The thesis
shows it after 0, 34, 35 and 44 applications, the handle parting at the 35th.

Applies global smoothing one application at a time (`tool.apply {"tool":"smooth","global":true,
"iterations":1}`), counts the solid's 6-connected components after each (`session.stats`), and
reports the application at which the count goes from 1 to 2. Writes dumbbell_NNN.png after 0,
pinch - 1 (by undo), pinch (by redo) and pinch + 9 applications (the thesis's spacing), and
checks that the two parts are still there 9 applications later.

    python3 examples/fig710_dumbbell.py --url ws://127.0.0.1:8080/ws
"""

import _common


async def main(a):
    async with _common.Client.connect(a.url) as client:
        opened = await client.create_session(a.size, "dumbbell")
        camera = _common.default_camera(opened["size"], 40)
        history = []  # (application, components, inside volume)
        frames = {}

        async def record(application):
            stats = await client.stats()
            history.append((application, stats["components"], stats["inside_volume"]))
            return stats

        async def render(application):
            image = await client.frame(camera, a.width, a.height, "png")
            frames[application] = _common.write_frame(a.out_dir, f"dumbbell_{application:03d}.png", image)

        start = await record(0)
        await render(0)
        if start["components"] != 1:
            raise SystemExit(f"the dumbbell starts with {start['components']} components, not 1")
        pinch = None
        for application in range(1, a.max_applications + 1):
            await client.apply("smooth", global_=True, iterations=1)
            stats = await record(application)
            if stats["components"] == 2:
                pinch = application
                break
        if pinch is None:
            raise SystemExit(f"no pinch-off within {a.max_applications} applications")
        # Undo gives back exactly the volume before the last application, redo the one after.
        await client.undo()
        await render(pinch - 1)
        await client.redo()
        await render(pinch)
        for application in range(pinch + 1, pinch + 10):
            await client.apply("smooth", global_=True, iterations=1)
            last = await record(application)
        await render(pinch + 9)

    # Each part's size, as the radius of a sphere of half the volume; the spheres start at 0.17 N.
    radius = _common.equivalent_radius({"inside_volume": history[pinch][2] / 2})
    print(f"Fig. 7.10: the dumbbell ({a.size}^3) under mean curvature flow")
    _common.print_table(["applications", "components", "volume vu^3"],
                        [[n, c, round(v, 1)] for n, c, v in history if n in (0, pinch - 1, pinch, pinch + 9)])
    print(f"the handle pinches off at application {pinch} (thesis: 35); "
          f"{last['components']} components 9 applications later; each part then holds a sphere of "
          f"radius {radius:.1f} vu (the spheres started at {0.17 * a.size:.1f})")
    _common.print_summary({"figure": "7.10", "size": a.size, "pinch_application": pinch,
                           "components_before": history[pinch - 1][1], "components_at_pinch": history[pinch][1],
                           "components_after_9": last["components"],
                           "volume_at_pinch": round(history[pinch][2], 1),
                           "part_radius_at_pinch": round(radius, 2), "frames": frames})


if __name__ == "__main__":
    p = _common.parser("Fig. 7.10: the dumbbell pinching off", "fig710", 64)
    p.add_argument("--max-applications", type=int, default=400,
                   help="give up after this many applications (default %(default)s)")
    _common.run(main(p.parse_args()))
