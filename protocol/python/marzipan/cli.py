"""`python3 -m marzipan batch`: the networked twin of `marzipan batch` (README, "The `marzipan`
command line"). It sends a file of operation objects, one JSON object per line, to a server's
session and saves the mesh, volume file or picture of the result.

Conventions: the ops file is that of `marzipan batch` (blank lines and lines starting with `#`
skipped, `-` reads standard input); coordinates in vu, y up; stats lines on stdout have the keys
of `marzipan batch --stats`, `ms` being the time spent in operation round trips. Exit status:
0 success, 1 bad input (a line that is not a JSON object, an operation the server refused, a
file that cannot be read or written), 2 usage, 3 the server could not be reached or closed the
connection. Output files are written only after every operation succeeded.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
import struct
import sys
import time

from .rpc import ConnectionClosed, ProtocolError, RpcError

EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_CONNECTION = 0, 1, 2, 3
DEFAULT_URL = "ws://127.0.0.1:8080/ws"
_MESH_FORMATS = {".stl": "stl", ".obj": "obj", ".ply": "ply", ".glb": "glb"}
_IMAGE_FORMATS = {".png": "png", ".jpg": "jpeg", ".jpeg": "jpeg"}
_SOLIDS = ("empty", "sphere", "box", "torus", "cylinder", "dumbbell", "pig")
# The direction of the default view, from the target towards the eye: front right and above
# (the pig faces +x, y is up), as `marzipan batch` frames its pictures.
_DEFAULT_VIEW = (0.55, 0.42, 0.72)


class InputError(Exception):
    """Bad input: reported as `where: reason`, exit status 1."""


def _refuse_constant(name):
    raise ValueError(f"{name} is not a number JSON allows")


def _no_repeated_keys(pairs):
    seen = set()
    for key, _ in pairs:
        if key in seen:
            raise ValueError(f'key "{key}" appears twice')
        seen.add(key)
    return dict(pairs)


def read_ops(path: str) -> list:
    """[(line number, operation object)] of an ops file; raises InputError naming the line for
    text that is not one JSON object (the server checks the fields). Repeated keys and numbers
    beyond double range are refused here because the JSON re-sent to the server would hide them."""
    try:
        if path == "-":
            text = sys.stdin.read()
        else:
            with open(path, encoding="utf-8") as f:
                text = f.read()
    except OSError as e:
        raise InputError(f"{path}: {e.strerror or e}") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not UTF-8 text") from None
    ops = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        try:
            op = json.loads(stripped, object_pairs_hook=_no_repeated_keys, parse_constant=_refuse_constant)
            if not isinstance(op, dict):
                raise ValueError("an operation must be a JSON object")
            json.dumps(op, allow_nan=False)
        except ValueError as e:
            message = str(e) if "Out of range float" not in str(e) else "a number is beyond double range"
            raise InputError(f"{path}:{number}: {message}") from None
        ops.append((number, op))
    return ops


def volume_file_size(data: bytes) -> list:
    """[nx, ny, nz] from the header of a .mzv file (server/engine/volume_file.hpp: "MZVF", u32
    version, three u32 dims, little-endian)."""
    if len(data) < 48 or data[:4] != b"MZVF":
        raise ValueError("not a .mzv volume file")
    return list(struct.unpack_from("<3I", data, 8))


def default_camera(size, fov: float, target=None) -> dict:
    """The view `marzipan batch` renders by default: looking at `target` (default the domain's
    centre) from the front right and above, at the distance where the sphere inscribed in the
    domain fills the vertical field of view."""
    if target is None:
        target = [(n - 1) / 2 for n in size]
    radius = 0.5 * max(size)
    half_fov = min(max(fov, 1.0), 170.0) * 0.5 * math.pi / 180
    length = math.sqrt(sum(c * c for c in _DEFAULT_VIEW))
    distance = radius / math.sin(half_fov)
    eye = [t + c / length * distance for t, c in zip(target, _DEFAULT_VIEW)]
    return {"eye": eye, "target": list(target)}


def stats_line(stats: dict, ms: float) -> str:
    """A stats line with the keys and order of `marzipan batch --stats`: session.stats's
    revision and measures, as the server gives them, then ms."""
    keys = ("revision", "inside_volume", "surface_area", "components", "bounds", "gradient_error", "digest")
    line = {key: stats[key] for key in keys}
    line["ms"] = round(ms, 3)
    return json.dumps(line, separators=(",", ":"))


def _vec3(text: str) -> list:
    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"{text!r} is not X,Y,Z (three finite numbers)")
    return values


def _int_in(lo: int, hi: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer in [{lo}, {hi}]")
        return value

    return parse


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python3 -m marzipan",
        description="Marzipan protocol client. `batch` sends an ops file to a server.")
    commands = parser.add_subparsers(dest="command", required=True)
    b = commands.add_parser(
        "batch", help="apply a .jsonl file of operation objects in a server session",
        description="Applies a file of operation objects (one JSON object per line, as for "
                    "`marzipan batch`) in a new session on a server, or in one it joins, and "
                    "writes a mesh, a volume file or a picture of the result.")
    b.add_argument("ops", help="the .jsonl file of operation objects; - reads standard input")
    b.add_argument("--url", default=os.environ.get("MARZIPAN_URL", DEFAULT_URL),
                   help="the server's WebSocket URL (default $MARZIPAN_URL or %(default)s)")
    b.add_argument("--size", type=_int_in(8, 1024), help="a new session of N^3 voxels (default 128)")
    b.add_argument("--solid", choices=_SOLIDS, help="the new session's starting solid (default sphere)")
    b.add_argument("--load", metavar="FILE.mzv", help="start from a volume file (a session of its size)")
    b.add_argument("--join", metavar="SESSION", help="work in this existing session instead of a new one")
    b.add_argument("--token", help="the edit token of --join's session")
    b.add_argument("--out", metavar="FILE",
                   help="write the result: .stl .obj .ply .glb (mesh, vu), .mzv, or .vdb (servers with OpenVDB)")
    b.add_argument("--max-triangles", type=_int_in(1, (1 << 32) - 1), metavar="N",
                   help="decimate the --out mesh to at most N triangles")
    b.add_argument("--max-error", type=float, metavar="E",
                   help="decimate the --out mesh while the error estimate stays within E vu")
    b.add_argument("--render", metavar="FILE", help="ray-cast a picture of the result: .png or .jpg")
    b.add_argument("--camera-eye", type=_vec3, metavar="X,Y,Z")
    b.add_argument("--camera-target", type=_vec3, metavar="X,Y,Z", help="default: the domain's centre")
    b.add_argument("--camera-up", type=_vec3, metavar="X,Y,Z", help="default: 0,1,0")
    b.add_argument("--fov", type=float, default=40.0, help="vertical field of view in degrees (default 40)")
    b.add_argument("--width", type=_int_in(1, 4096), default=512)
    b.add_argument("--height", type=_int_in(1, 4096), default=512)
    b.add_argument("--shading", choices=("lit", "normals", "gradient_error"))
    b.add_argument("--quality", type=_int_in(1, 100), help="JPEG quality (default 90)")
    b.add_argument("--stats", action="store_true", help="print a stats line after the last operation")
    b.add_argument("--stats-every", type=_int_in(1, 1 << 31), metavar="K",
                   help="print a stats line after every K operations, and after the last")
    b.add_argument("--print-session", action="store_true",
                   help="print {session, token, view_token} on stderr once the session is open")
    return parser


def _check_usage(parser, a):
    def fail(message):
        parser.error(message)

    if a.join and (a.size or a.solid):
        fail("--join works in an existing session: no --size or --solid")
    if a.join and not a.token:
        fail("--join needs --token")
    if a.token and not a.join:
        fail("--token goes with --join")
    if a.load and (a.size or a.solid):
        fail("--load starts from the file: no --size or --solid")
    if a.load and not a.load.lower().endswith(".mzv"):
        fail("--load takes a .mzv volume file over the network (meshes: `marzipan batch --load`)")
    if a.out and os.path.splitext(a.out)[1].lower() not in (*_MESH_FORMATS, ".mzv", ".vdb"):
        fail(f"--out {a.out}: the extension must be .stl, .obj, .ply, .glb, .mzv or .vdb")
    decimate = a.max_triangles is not None or a.max_error is not None
    if decimate and (not a.out or a.out.lower().endswith((".mzv", ".vdb"))):
        fail("--max-triangles and --max-error apply to a mesh written with --out")
    if a.max_error is not None and not (0 < a.max_error <= 1e6):
        fail("--max-error takes a number of vu above 0")
    if a.render and os.path.splitext(a.render)[1].lower() not in _IMAGE_FORMATS:
        fail(f"--render {a.render}: the extension must be .png or .jpg")
    if not a.render and (a.camera_eye or a.camera_target or a.camera_up or a.shading or a.quality):
        fail("camera and image options need --render FILE")
    if not 1 < a.fov < 170:
        fail("--fov must be in (1, 170)")


def _write(path: str, data: bytes):
    try:
        with open(path, "wb") as f:
            f.write(data)
    except OSError as e:
        raise InputError(f"{path}: {e.strerror or e}") from None


async def run_batch(a) -> int:
    from .client import Client, ConnectFailed

    ops = read_ops(a.ops)
    upload = None
    if a.load:
        try:
            with open(a.load, "rb") as f:
                upload = f.read()
            size = volume_file_size(upload)
        except OSError as e:
            raise InputError(f"{a.load}: {e.strerror or e}") from None
        except ValueError as e:
            raise InputError(f"{a.load}: {e}") from None
    else:
        size = [a.size or 128] * 3
    try:
        client = await Client.connect(a.url, session=a.join)
    except ConnectFailed as e:
        print(f"marzipan: {e}", file=sys.stderr)
        return EXIT_CONNECTION
    try:
        if a.join:
            opened = await client.join(a.join, a.token)
            size = opened["size"]
        else:
            opened = await client.create_session(size, "empty" if upload else (a.solid or "sphere"))
        if a.print_session:
            print(json.dumps({"session": client.session, "token": client.token,
                              "view_token": client.view_token}), file=sys.stderr, flush=True)
        if upload is not None:
            try:
                await client.load(upload)
            except RpcError as e:
                raise InputError(f"{a.load}: {e.message}") from None
        ms = 0.0
        reported = False
        for index, (number, op) in enumerate(ops, start=1):
            started = time.perf_counter()
            try:
                await client.apply_op(op)
            except RpcError as e:
                raise InputError(f"{a.ops}:{number}: {e.message}") from None
            ms += (time.perf_counter() - started) * 1000
            reported = False
            if a.stats_every and index % a.stats_every == 0:
                print(stats_line(await client.stats(), ms), flush=True)
                reported = True
        if (a.stats or a.stats_every) and not reported:
            print(stats_line(await client.stats(), ms), flush=True)
        outputs = []
        if a.out:
            ext = os.path.splitext(a.out)[1].lower()
            if ext in (".mzv", ".vdb"):
                data = await client.save(format=ext[1:])
            elif a.max_triangles is not None or a.max_error is not None:
                result, data = await client.export_mesh_with_result(_MESH_FORMATS[ext], a.max_triangles, a.max_error)
                print(json.dumps({"mesh": a.out, "source_triangles": result["source_triangles"],
                                  "triangles": result["triangles"], "vertices": result["vertices"],
                                  "max_error": result["max_error"]}), flush=True)
            else:
                data = await client.export_mesh(_MESH_FORMATS[ext])
            outputs.append((a.out, data))
        if a.render:
            camera = default_camera(size, a.fov, a.camera_target)
            if a.camera_eye:
                camera["eye"] = a.camera_eye
            if a.camera_up:
                camera["up"] = a.camera_up
            camera["fov"] = a.fov
            image_format = _IMAGE_FORMATS[os.path.splitext(a.render)[1].lower()]
            try:
                image = await client.frame(camera, a.width, a.height, image_format,
                                           quality=a.quality, shading=a.shading)
            except RpcError as e:
                print(f"marzipan batch: camera: {e.message}", file=sys.stderr)
                return EXIT_USAGE
            outputs.append((a.render, image))
        for path, data in outputs:
            _write(path, data)
        return EXIT_OK
    except RpcError as e:
        print(f"marzipan: {e}", file=sys.stderr)
        return EXIT_INPUT
    except (ConnectionClosed, ConnectFailed, ProtocolError) as e:
        print(f"marzipan: {e}", file=sys.stderr)
        return EXIT_CONNECTION
    finally:
        await client.close()


def main(argv=None) -> int:
    parser = _parser()
    a = parser.parse_args(argv)
    _check_usage(parser, a)
    try:
        return asyncio.run(run_batch(a))
    except InputError as e:
        print(e, file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        return 130
