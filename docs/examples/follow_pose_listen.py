#!/usr/bin/env python3
"""Follows one robot's fused pose, read from roomfix listen's JSON lines.

    roomfix listen --channel POSE_FUSED | python3 follow_pose_listen.py --robot 1

Needs no LCM module: roomfix listen decodes (refusing malformed messages)
and prints one JSON object per line. Prints one line per pose of the robot:
utime, x_m, y_m, heading in degrees (nan when unknown), status.
"""
import argparse
import json
import math
import sys

STATUS = {0: "ok", 1: "degraded", 2: "lost"}  # pose2d_t.STATUS_*

parser = argparse.ArgumentParser(description="Follow one robot's POSE_FUSED")
parser.add_argument("--robot", type=int, default=1, help="the site's robot id")
args = parser.parse_args()

for line in sys.stdin:
    event = json.loads(line)
    pose = event.get("message")
    if pose is None:  # refused by listen: {"refused": reason, "error": words}
        print(f"{event['channel']}: refused ({event['refused']})", file=sys.stderr)
        continue
    if pose["type"] != "roomfix.pose2d_t" or pose["robot_id"] != args.robot:
        continue
    # NaN (unknown heading, a lost pose's position) arrives as null.
    x, y, heading = (v if v is not None else math.nan
                     for v in (pose["x_m"], pose["y_m"], pose["heading_rad"]))
    print(f"{pose['utime']} {x:.4f} {y:.4f} {math.degrees(heading):.1f} "
          f"{STATUS[pose['status']]}", flush=True)
