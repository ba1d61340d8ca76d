#!/usr/bin/env python3
"""Follows one robot's fused pose on the bus with LCM's Python module.

    python3 follow_pose_lcm.py --robot 1

Needs `lcm` (pip install lcm, LCM 1.5 or later) and roomfix's Python types
(the roomfix package installs them; from a build tree,
PYTHONPATH=build/python). Prints what follow_pose_listen.py prints.
"""
import argparse
import math
import struct
import sys

import lcm
from roomfix import pose2d_t

STATUS = {pose2d_t.STATUS_OK: "ok", pose2d_t.STATUS_DEGRADED: "degraded",
          pose2d_t.STATUS_LOST: "lost"}

parser = argparse.ArgumentParser(description="Follow one robot's POSE_FUSED")
parser.add_argument("--robot", type=int, default=1, help="the site's robot id")
parser.add_argument("--count", type=int, default=0, help="stop after this many poses (0: never)")
parser.add_argument("--lcm-url", default="", help="LCM URL (default: LCM's, as roomfix's)")
args = parser.parse_args()
poses = 0


def on_pose(channel, data):
    global poses
    try:
        pose = pose2d_t.decode(data)
    except (ValueError, struct.error) as e:  # another type, or cut short
        print(f"{channel}: not a pose2d_t ({e!r})", file=sys.stderr)
        return
    # decode() checks the fingerprint, not what roomfix's DecodeChecked
    # also refuses (caps, trailing bytes, enum values): check what is used.
    if pose.robot_id != args.robot or pose.status not in STATUS:
        return
    print(f"{pose.utime} {pose.x_m:.4f} {pose.y_m:.4f} {math.degrees(pose.heading_rad):.1f} "
          f"{STATUS[pose.status]}", flush=True)
    poses += 1


bus = lcm.LCM(args.lcm_url) if args.lcm_url else lcm.LCM()
bus.subscribe("POSE_FUSED", on_pose)
print(f"following robot {args.robot} on POSE_FUSED", file=sys.stderr, flush=True)
while args.count == 0 or poses < args.count:
    bus.handle()
