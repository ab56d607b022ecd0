#!/usr/bin/env python3
"""Reads marzipan-bench JSON lines on stdin and prints the Table 7.2 reproduction as markdown:
per ROI side, the seconds per application of Bærentzen's thesis (2002) and Marzipan's milliseconds
(the median wall-clock time, and the median CPU time, which a shared machine disturbs less)."""
import json
import sys

rows = {}
for line in sys.stdin:
    line = line.strip()
    if not line.startswith("{"):
        continue
    j = json.loads(line)
    if j["scenario"] not in ("table72_add_blob", "table72_smooth"):
        continue
    rows.setdefault(j["roi"], {})[j["scenario"]] = j

print("| ROI side | band voxels | add blob: thesis (Athlon, 2001) | add blob: Marzipan | speed-up | smoothing: thesis | smoothing: Marzipan | speed-up |")
print("| --- | --- | --- | --- | --- | --- | --- | --- |")
for roi in sorted(rows):
    a, s = rows[roi].get("table72_add_blob"), rows[roi].get("table72_smooth")
    def cells(j):
        if j is None:
            return ["", "", ""]
        seed = f'{j["seed_ms"]:.0f} ms' if "seed_ms" in j else "—"
        up = f'{j["speedup_vs_seed"]:.0f}x' if "speedup_vs_seed" in j else "—"
        ms = f'{j["median_ms"]:.2f} ms'
        if "cpu_median_ms" in j:
            ms += f' (CPU {j["cpu_median_ms"]:.2f})'
        return [seed, ms, up]
    band = (a or s)["band_voxels"]
    print(f"| {roi}^3 | {band} | " + " | ".join(cells(a) + cells(s)) + " |")
