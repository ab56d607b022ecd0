#!/usr/bin/python3
"""marzipan-bench's instruction mode: instructions per timed call, a figure that holds still on
a shared machine where milliseconds do not (issue 32, decision 2).

    tests/bench/instructions.py --bench build/tests/bench/marzipan-bench [--quick] [--threads 1] SCENARIO...

runs the scenarios under `valgrind --tool=callgrind --collect-atstart=no`, where marzipan-bench
collects only the calls measure() times and dumps each measurement apart (bench.hpp), and
prints marzipan-bench's JSON lines with each "measurement" key replaced by "instructions", the
mean instructions (callgrind's Ir, all threads) per timed call: "measurement" becomes
"instructions", "one_dab_measurement" "one_dab_instructions". The milliseconds in those lines
are callgrind's, tens of times the real ones: take them from a run without it. Hardware counters
(`perf stat -e instructions`) would be quicker, but this project's VMs do not expose them
("<not supported>", 2026-11-29). Exit status: marzipan-bench's; 1 when valgrind is missing, a
line names a measurement that was not dumped, or no line names one (a marzipan-bench built
without valgrind/callgrind.h counts nothing).
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

_PART = re.compile(r"^desc: Trigger: Client Request: marzipan-bench measurement (\d+) reps (\d+)$", re.M)
_TOTAL = re.compile(r"^(?:summary|totals): (\d+)", re.M)


def instructions_by_measurement(directory: str) -> dict:
    """{measurement: mean Ir per timed call} from callgrind's dumps in `directory`."""
    out = {}
    for path in glob.glob(os.path.join(directory, "callgrind.out*")):
        with open(path) as f:
            text = f.read()
        part, total = _PART.search(text), _TOTAL.search(text)
        if part and total:
            out[int(part.group(1))] = int(total.group(1)) / int(part.group(2))
    return out


def with_instructions(line: dict, counts: dict) -> dict:
    out = {}
    for key, value in line.items():
        if key.endswith("measurement"):
            if value not in counts:
                raise KeyError(f"{line.get('scenario')}: measurement {value} has no callgrind dump")
            out[key[: -len("measurement")] + "instructions"] = round(counts[value])
        else:
            out[key] = value
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--bench", required=True, help="the marzipan-bench binary")
    p.add_argument("--threads", type=int, default=1, help="marzipan-bench --threads (default %(default)s)")
    p.add_argument("--quick", action="store_true", help="marzipan-bench --quick")
    p.add_argument("scenarios", nargs="+")
    args = p.parse_args(argv)
    valgrind = shutil.which("valgrind")
    if not valgrind:
        print("instructions.py: valgrind not found", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as directory:
        command = [valgrind, "--tool=callgrind", "--collect-atstart=no",
                   f"--callgrind-out-file={os.path.join(directory, 'callgrind.out')}",
                   args.bench, "--threads", str(args.threads), *(["--quick"] if args.quick else []), *args.scenarios]
        run = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if run.returncode != 0:
            sys.stderr.write(run.stderr[-4000:])
            return run.returncode
        counts = instructions_by_measurement(directory)
        lines = [json.loads(text) for text in run.stdout.splitlines()]
        try:
            out = [with_instructions(line, counts) for line in lines]
        except KeyError as e:
            print(f"instructions.py: {e.args[0]}", file=sys.stderr)
            return 1
    if not any("instructions" in line for line in out):
        print("instructions.py: no line carries a measurement (marzipan-bench built without valgrind/callgrind.h?)",
              file=sys.stderr)
        return 1
    for line in out:
        print(json.dumps(line, separators=(",", ":")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
