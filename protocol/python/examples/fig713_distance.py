"""Fig. 7.13 of Bærentzen's thesis (2002, docs/method.md) and section 7.6.0.4: 400 add-blob and 400
smoothing applications at random on one face of a cube, after which the field should still be a
distance field: the thesis found | |grad d| - 1 | nowhere above 0.07 vu, largest near the edges.

The cube is the `box` solid (half side 0.25 N; N = 80 gives the 20 vu of the engine's own test),
the tools work on its +x face at random centres within 10 vu of the face's middle, radius 4-8,
strength 0.2-1, add blob and smoothing in turn. Then the server renders the face head-on twice:
lit (fig713_lit.png) and with `shading: gradient_error` (fig713_gradient_error.png), where each
pixel is the largest | |grad d| - 1 | at the 8 corners of the cell its ray hits, as a grey level
(0 black, 0.1 vu and more white), the thesis's measure. The figures read from that image:
the largest and mean error over the middle of the face (within 8 vu of its centre, which every
application's window covers evenly: the thesis's condition of little curvature), and over
every pixel of the solid (where the cube's untouched sharp edges saturate it); plus the
session's own gradient_error over every voxel next to the surface.

    python3 examples/fig713_distance.py --url ws://127.0.0.1:8080/ws
"""

import math
import random
import time

import _common

from marzipan.png import decode_png

WHITE_ERROR = 0.1  # vu: the error that renders white (server/engine/raycast.cpp)
SPREAD = 10.0  # vu: the tools' centres lie within this of the face's middle, per axis
MIDDLE = 8.0  # vu: half side of the square of the face measured as "the middle"
FOV = 40.0


def image_errors(png: bytes, distance: float, half_side: float):
    """Errors (vu) of the gradient-error frame of a camera `distance` vu in front of the face,
    looking straight at it: those of the pixels whose rays meet the face's plane within
    `half_side` vu of its centre, and those of every pixel showing the solid (grey ones: the
    background's gradient is bluish)."""
    width, height, channels, pixels = decode_png(png)
    tan_half = math.tan(math.radians(FOV) / 2)
    middle, solid = [], []
    for y in range(height):
        # The ray through the pixel's centre meets the plane this far right and up of the
        # centre (server/engine/README.md, "Camera").
        up = distance * (1 - 2 * (y + 0.5) / height) * tan_half
        for x in range(width):
            i = (y * width + x) * channels
            r, g, b = pixels[i], pixels[i + 1], pixels[i + 2]
            if not r == g == b:
                continue
            error = r / 255 * WHITE_ERROR
            solid.append(error)
            right = distance * (2 * (x + 0.5) / width - 1) * tan_half * width / height
            if abs(right) <= half_side and abs(up) <= half_side:
                middle.append(error)
    return middle, solid


async def main(a):
    rng = random.Random(a.seed)
    async with _common.Client.connect(a.url) as client:
        await client.create_session(a.size, "box")
        before = await client.stats()
        face = before["bounds"]["hi"][0]
        cy = (before["bounds"]["lo"][1] + before["bounds"]["hi"][1]) / 2
        cz = (before["bounds"]["lo"][2] + before["bounds"]["hi"][2]) / 2
        started = time.perf_counter()
        for i in range(a.applications):
            center = [face, cy + rng.uniform(-SPREAD, SPREAD), cz + rng.uniform(-SPREAD, SPREAD)]
            tool = "add_blob" if i % 2 == 0 else "smooth"
            await client.apply(tool, center=center, radius=rng.uniform(4, 8), strength=rng.uniform(0.2, 1.0))
        elapsed_ms = (time.perf_counter() - started) * 1000
        after = await client.stats()
        # Far enough that the face's 2 x 0.25 N side fills about 80% of the view's height.
        distance = 0.25 * a.size / 0.8 / math.tan(math.radians(FOV) / 2) + (after["bounds"]["hi"][0] - face)
        camera = {"eye": [face + distance, cy, cz], "target": [face, cy, cz], "up": [0, 1, 0], "fov": FOV}
        lit = await client.frame(camera, a.width, a.height, "png")
        error_png = await client.frame(camera, a.width, a.height, "png", shading="gradient_error")
    _common.write_frame(a.out_dir, "fig713_lit.png", lit)
    path = _common.write_frame(a.out_dir, "fig713_gradient_error.png", error_png)
    middle, solid = image_errors(error_png, distance, MIDDLE)
    figures = {
        "figure": "7.13", "size": a.size, "applications": a.applications, "seed": a.seed,
        "face_x": face, "face_moved_out": round(after["bounds"]["hi"][0] - face, 3),
        "middle_max_error": round(max(middle), 4), "middle_mean_error": round(sum(middle) / len(middle), 4),
        "middle_pixels": len(middle),
        "solid_max_error": round(max(solid), 4),
        "solid_pixels_at_or_over_0.07": round(sum(1 for e in solid if e >= 0.07) / len(solid), 4),
        "volume_gradient_error_max": round(after["gradient_error"]["max"], 4),
        "volume_gradient_error_mean": round(after["gradient_error"]["mean"], 5),
        "start_gradient_error_max": round(before["gradient_error"]["max"], 4),
        "ms_per_application": round(elapsed_ms / max(a.applications, 1), 2),
        "frame": path,
    }
    print(f"Fig. 7.13: {a.applications} random add-blob / smoothing applications on a face of a cube "
          f"({a.size}^3)")
    _common.print_table(["where", "max | |grad d| - 1 | (vu)", "mean (vu)"], [
        [f"image, middle of the face ({len(middle)} pixels)", figures["middle_max_error"],
         figures["middle_mean_error"]],
        [f"image, the whole solid ({len(solid)} pixels)", figures["solid_max_error"], "-"],
        ["every voxel next to the surface (session.stats)", figures["volume_gradient_error_max"],
         figures["volume_gradient_error_mean"]],
    ])
    print(f"thesis: nowhere above 0.07 vu; {100 * figures['solid_pixels_at_or_over_0.07']:.1f}% of the solid's "
          f"pixels reach 0.07 (the cube's sharp edges); the face moved out by {figures['face_moved_out']} vu; "
          f"{figures['ms_per_application']} ms per application")
    _common.print_summary(figures)


if __name__ == "__main__":
    p = _common.parser("Fig. 7.13: distance-field preservation over 800 applications", "fig713", 80)
    p.add_argument("--applications", type=int, default=800, help="add blob and smoothing in turn (default %(default)s)")
    p.add_argument("--seed", type=int, default=7, help="seed of the random centres, radii and strengths")
    _common.run(main(p.parse_args()))
