#!/usr/bin/env python3
"""Handover figures of a hall log (tests/netns/hall_test.sh, docs/fusion.md).

Reads the JSON lines of `roomfix listen --lcm-url file://LOG?speed=0` and
prints, per robot and over all robots:

  handovers   how often the set of cameras that see the robot changed (a
              camera's first or last pose of a stretch, after the warm-up)
  step_mm     the largest change of the fused error (fused pose minus the
              interpolated ground truth, a vector) from one fused pose at a
              camera frame's time to the next, in measurement time, within --window of a handover, both
              poses OK (held by a camera): how far the fused pose jumps when
              one camera takes over from another or lets go (the issue's
              bound: 1 cm). A return from DEGRADED (no camera frame for
              0.5 s: a loaded machine's camera_procs dropped every frame,
              and the ultrasound held the track) is a re-acquisition, not a
              handover: counted in `degraded`
  all_step_mm the same over every fused pose (also those at an ultrasonic
              fix's time), printed only: see below
  degraded    fused poses DEGRADED after the warm-up (ultrasound only)
  gap_ms      the longest time between two of those fused poses (not LOST)
  missed      the most frames in a row that the cameras around the robot
              processed without a pose of it: between two frames with a
              pose, the frames (MARKER_PIXELS in the log) of any camera that
              posed it on either side. A handover that drops the robot shows
              here; a frame a loaded camera_proc dropped as stale (counted
              in its STATUS, never processed) does not
  inside95    the share of fused poses whose error lies inside their own 95 %
              ellipse (e' S^-1 e <= 5.991, chi-square 2 dof), and the median
              of e' S^-1 e (2 ln 2 = 1.386 when calibrated)

and exits 1 when a step reaches --max-step-m, more than --max-missed frames
were missed in a row, or a robot has no handover (the trajectories cross
the borders: no handover means no camera saw one).

  hall_handover.py LOG_JSONL [--warmup-s 2] [--window-s 0.5] [--max-step-m 0.01]
                   [--max-missed 4]
"""

import argparse
import bisect
import json
import math
import sys
from collections import defaultdict

CHI2_2DOF_95 = 5.991
STATUS_OK = 0
STATUS_LOST = 2


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log_jsonl")
    parser.add_argument("--warmup-s", type=float, default=2.0)
    parser.add_argument("--window-s", type=float, default=0.5)
    parser.add_argument("--max-step-m", type=float, default=0.01)
    parser.add_argument("--max-missed", type=int, default=4)
    parser.add_argument("--explain", action="store_true",
                        help="print where each robot's largest step was (s after the start)")
    args = parser.parse_args()

    truth = defaultdict(list)  # robot -> [(utime, x, y)]
    camera = defaultdict(list)  # robot -> [(utime, camera_id)]
    fused = defaultdict(list)  # robot -> [(utime, x, y, cov or None, status)]
    frames = defaultdict(set)  # camera -> frame utimes it processed
    with open(args.log_jsonl) as f:
        for line in f:
            if not line.startswith("{"):
                continue
            event = json.loads(line)
            channel = event.get("channel")
            if channel == "MARKER_PIXELS":
                m = event["message"]
                frames[m["camera_id"]].add(m["utime"])
                continue
            if channel not in ("POSE_GROUND_TRUTH", "POSE_CAMERA", "POSE_FUSED"):
                continue
            m = event["message"]
            robot = m["robot_id"]
            if channel == "POSE_GROUND_TRUTH":
                truth[robot].append((m["utime"], m["x_m"], m["y_m"]))
            elif channel == "POSE_CAMERA":
                if m["status"] != STATUS_LOST:
                    camera[robot].append((m["utime"], m["camera_id"]))
            else:
                fused[robot].append((m["utime"], m["x_m"], m["y_m"], m["covariance"], m["status"]))
    if not fused:
        print("hall_handover: no POSE_FUSED in the log", file=sys.stderr)
        return 1
    start = min(p[0] for poses in fused.values() for p in poses) + args.warmup_s * 1e6

    def error_at(robot, utime, x, y):
        track = truth[robot]
        times = [t[0] for t in track]
        i = bisect.bisect_left(times, utime)
        if i == 0 or i == len(track):
            return None
        (t0, x0, y0), (t1, x1, y1) = track[i - 1], track[i]
        if t1 - t0 > 200000:  # No truth to interpolate over this long.
            return None
        a = (utime - t0) / (t1 - t0)
        return (x - (x0 + a * (x1 - x0)), y - (y0 + a * (y1 - y0)))

    failed = False
    all_steps, all_d2, worst_gap = [], [], 0
    all_frames = sorted(set().union(*frames.values())) if frames else []
    worst_missed = 0
    print("  robot handovers step_mm all_step_mm gap_ms missed degraded inside95 median_d2")
    for robot in sorted(fused):
        truth[robot].sort()
        # Handovers: per camera, the stretches in which it saw the robot
        # (frames at most 0.5 s apart); each stretch's start and end.
        by_camera = defaultdict(list)
        for utime, cam in sorted(camera[robot]):
            by_camera[cam].append(utime)
        events = []
        for times in by_camera.values():
            stretch_start = times[0]
            for prev, cur in zip(times, times[1:] + [None]):
                if cur is None or cur - prev > 500000:
                    events += [stretch_start, prev]
                    stretch_start = cur
        events = sorted(e for e in events if e >= start)
        # Missed frames: between consecutive posed instants, the frames of
        # the cameras that posed the robot on either side.
        posed = defaultdict(set)
        for utime, cam in camera[robot]:
            if utime >= start:
                posed[utime].add(cam)
        instants = sorted(posed)
        missed = 0
        for before, after in zip(instants, instants[1:]):
            around = posed[before] | posed[after]
            lo = bisect.bisect_right(all_frames, before)
            hi = bisect.bisect_left(all_frames, after)
            n = sum(1 for t in all_frames[lo:hi] if any(t in frames[c] for c in around))
            missed = max(missed, n)
        # Fused poses in measurement time; the last of equal times (the
        # filter's estimate after every measurement of that instant).
        poses = {}
        for p in fused[robot]:
            poses[p[0]] = p
        # Only the fused poses at a camera frame's time: an ultrasonic fix
        # that arrives ahead of frames still in a loaded camera_proc gets a
        # pose predicted over their delay (up to a second in a stall), which
        # the late frames then correct; that step is the pipeline's latency,
        # there with or without a handover. Its size is printed (all_step_mm)
        # but not bounded here.
        frame_times = {utime for utime, _ in camera[robot]}
        all_ordered = [poses[t] for t in sorted(poses) if t >= start]
        ordered = [p for p in all_ordered if p[0] in frame_times]
        steps, d2s, gap, last_ok = [], [], 0, None
        previous_error = None
        degraded = 0
        for utime, x, y, cov, status in ordered:
            if status == STATUS_LOST or x is None:
                previous_error = None
                continue
            camera_held = status == STATUS_OK
            if last_ok is not None:
                gap = max(gap, utime - last_ok)
            last_ok = utime
            e = error_at(robot, utime, x, y)
            if not camera_held:
                degraded += 1
            if e is None or not camera_held:
                previous_error = None
                if e is None:
                    continue
            elif previous_error is not None:
                i = bisect.bisect_left(events, utime - args.window_s * 1e6)
                if i < len(events) and events[i] <= utime + args.window_s * 1e6:
                    steps.append(math.hypot(e[0] - previous_error[0], e[1] - previous_error[1]))
                    if args.explain and steps[-1] == max(steps):
                        where = "at %.3f s: error (%.1f, %.1f) -> (%.1f, %.1f) mm" % (
                            (utime - start) / 1e6 + args.warmup_s, previous_error[0] * 1e3,
                            previous_error[1] * 1e3, e[0] * 1e3, e[1] * 1e3)
            if camera_held:
                previous_error = e
            sxx, sxy, syy = cov[0], cov[1], cov[4]
            det = sxx * syy - sxy * sxy
            if det > 0:
                d2s.append((syy * e[0] * e[0] - 2 * sxy * e[0] * e[1] + sxx * e[1] * e[1]) / det)
        all_step, prev = 0.0, None
        for utime, x, y, cov, status in all_ordered:
            e = error_at(robot, utime, x, y) if status == STATUS_OK and x is not None else None
            if e is not None and prev is not None:
                i = bisect.bisect_left(events, utime - args.window_s * 1e6)
                if i < len(events) and events[i] <= utime + args.window_s * 1e6:
                    all_step = max(all_step, math.hypot(e[0] - prev[0], e[1] - prev[1]))
            prev = e
        step = max(steps) if steps else float("nan")
        inside = sum(d <= CHI2_2DOF_95 for d in d2s) / len(d2s) if d2s else float("nan")
        median = sorted(d2s)[len(d2s) // 2] if d2s else float("nan")
        print("  %5d %9d %7.2f %11.2f %6.0f %6d %8d %7.1f%% %9.2f"
              % (robot, len(events), step * 1e3, all_step * 1e3, gap / 1e3, missed, degraded,
                 100 * inside, median))
        worst_missed = max(worst_missed, missed)
        if args.explain and steps:
            print("        largest step " + where)
        if missed > args.max_missed:
            print("hall_handover: robot %d: %d frames in a row without it from the cameras "
                  "around it (at most %d)" % (robot, missed, args.max_missed), file=sys.stderr)
            failed = True
        all_steps += steps
        all_d2 += d2s
        worst_gap = max(worst_gap, gap)
        if not events:
            print("hall_handover: robot %d: no handover seen" % robot, file=sys.stderr)
            failed = True
        if steps and step >= args.max_step_m:
            print("hall_handover: robot %d: fused step %.1f mm at a handover (bound %.0f mm)"
                  % (robot, step * 1e3, args.max_step_m * 1e3), file=sys.stderr)
            failed = True
    inside = sum(d <= CHI2_2DOF_95 for d in all_d2) / max(1, len(all_d2))
    median = sorted(all_d2)[len(all_d2) // 2] if all_d2 else float("nan")
    print("  all: largest fused step at a handover %.2f mm, longest gap between fused poses "
          "%.0f ms, at most %d frames missed in a row, %.1f %% inside the 95 %% ellipse "
          "(median d2 %.2f, %d poses)"
          % (max(all_steps, default=float("nan")) * 1e3, worst_gap / 1e3, worst_missed,
             100 * inside, median, len(all_d2)))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
