#!/usr/bin/env python3
"""roomfix export's CSVs reproduce roomfix compare's error figures.

Exports a recorded log of the demo's pipeline (camera, ultrasound, fused and
ground truth poses) with `roomfix export LOG --csv DIR`, then recomputes,
from the CSV files alone (with Python's csv module, as a user would with
pandas), each source's error against ground truth the way `roomfix compare`
defines it (docs/export.md, "Recomputing roomfix compare"):
  - a track per (source_name, robot_id) over every POSE_* file, lost poses
    and poses without a position left out, sorted by utime, a pose recorded
    twice (same utime, x, y) counted once;
  - each pose's horizontal error against the ground truth track linearly
    interpolated at its utime, where the two ground truth samples around it
    are at most 0.2 s apart;
  - RMSE, and the maximum, over the poses compared.
and checks them against compare's JSON and its printed table.
"""
import argparse
import bisect
import csv
import json
import math
import os
import subprocess
import sys
import tempfile

# compare's kMaxReferenceGap_us (tools/compare_command.cc).
MAX_REFERENCE_GAP_US = 200000
# The CSV holds every double in the shortest form that reads back to the
# same bits, and the errors are summed in the same order as compare does;
# what may differ is the last bit of Python's math.hypot against C++'s
# std::hypot for each error, far below this.
RMSE_TOLERANCE_M = 1e-12
# compare prints metres to 4 decimals: the printed figure is within half a
# unit of its last digit (plus the tolerance above).
PRINTED_TOLERANCE_M = 0.5e-4 + RMSE_TOLERANCE_M


def read_tracks(folder):
    tracks = {}
    with open(os.path.join(folder, "_channels.csv"), newline="") as f:
        files = [row for row in csv.DictReader(f) if row["type"] == "roomfix.pose2d_t"
                 and row["channel"].startswith("POSE_")]
    for entry in files:
        with open(os.path.join(folder, entry["file"]), newline="") as f:
            for row in csv.DictReader(f):
                if row["status_name"] == "lost" or row["x_m"] == "" or row["y_m"] == "":
                    continue
                key = (row["source_name"], int(row["robot_id"]))
                tracks.setdefault(key, []).append(
                    (int(row["utime"]), float(row["x_m"]), float(row["y_m"])))
    for key, track in tracks.items():
        track.sort(key=lambda p: p[0])  # stable, as compare's
        deduplicated = [p for i, p in enumerate(track) if i == 0 or p != track[i - 1]]
        tracks[key] = deduplicated
    return tracks


def interpolate(reference, times, utime):
    i = bisect.bisect_left(times, utime)
    if i == len(reference):
        return None
    if reference[i][0] == utime:
        return reference[i][1:]
    if i == 0:
        return None
    (t0, x0, y0), (t1, x1, y1) = reference[i - 1], reference[i]
    if t1 - t0 > MAX_REFERENCE_GAP_US:
        return None
    f = (utime - t0) / (t1 - t0)
    return x0 + f * (x1 - x0), y0 + f * (y1 - y0)


def errors_against(track, reference):
    times = [p[0] for p in reference]
    errors = []
    for utime, x, y in track:
        at = interpolate(reference, times, utime)
        if at is not None:
            errors.append(math.hypot(x - at[0], y - at[1]))
    return errors


def printed_rmse(stdout):
    """(source, robot) -> rmse_m from compare's table."""
    out = {}
    lines = stdout.splitlines()
    header = lines[0].split()
    for line in lines[1:]:
        cells = line.split()
        if len(cells) != len(header):
            break
        row = dict(zip(header, cells))
        out[(row["source"], int(row["robot"]))] = float(row["rmse_m"])
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--roomfix", required=True)
    p.add_argument("--log", required=True)
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = os.path.join(tmp, "csv")
        export = subprocess.run([args.roomfix, "export", args.log, "--csv", folder],
                                capture_output=True, text=True)
        if export.returncode != 0:
            print(f"FAIL: roomfix export exited {export.returncode}: {export.stderr}")
            return 1
        tracks = read_tracks(folder)
        compare = subprocess.run([args.roomfix, "compare", args.log, "--json",
                                  os.path.join(tmp, "compare.json")],
                                 capture_output=True, text=True, check=True)
        with open(os.path.join(tmp, "compare.json")) as f:
            summary = json.load(f)
    printed = printed_rmse(compare.stdout)
    failures = checked = 0
    for (source, robot), track in sorted(tracks.items()):
        if source == "ground_truth":
            continue
        truth = tracks.get(("ground_truth", robot))
        want = summary["robots"][str(robot)][source]
        if truth is None:
            print(f"FAIL: no ground truth for robot {robot} in the CSVs")
            failures += 1
            continue
        errors = errors_against(track, truth)
        rmse = math.sqrt(sum(e * e for e in errors) / len(errors))
        line = (f"{source:12} robot {robot}: {len(errors)} compared, RMSE {rmse:.6f} m from the "
                f"CSV, compare {want['rmse_m']:.6f} m (printed {printed[(source, robot)]:.4f})")
        ok = (len(errors) == want["compared"] and len(track) == want["fixes"] and
              abs(rmse - want["rmse_m"]) <= RMSE_TOLERANCE_M and
              abs(max(errors) - want["max_m"]) <= RMSE_TOLERANCE_M and
              abs(rmse - printed[(source, robot)]) <= PRINTED_TOLERANCE_M)
        print(("" if ok else "FAIL: ") + line)
        failures += not ok
        checked += 1
    if checked < 3:
        print(f"FAIL: only {checked} sources compared; the log should give camera, ultrasound "
              "and fused")
        return 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
