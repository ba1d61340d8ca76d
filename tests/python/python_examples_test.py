#!/usr/bin/env python3
"""Runs docs/python.md's two examples on a recorded log.

  pipe: roomfix listen on the log (file://...?speed=0) | python3
        docs/examples/follow_pose_listen.py: no LCM module needed.
  lcm:  docs/examples/follow_pose_lcm.py subscribed with LCM's Python module
        while the real lcm-logplayer plays the log on UDP multicast (run it
        inside scripts/netns_run); exits 77 (skipped), saying why, when
        `import lcm` fails or lcm-logplayer is missing.

Either way the example must print one line for every POSE_FUSED pose of the
log's robot, exactly as computed here from the poses the C++ side decoded
(roomfix_lcm_samples), and docs/python.md must show the example's code as
the file holds it.
"""
import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import threading

SKIP = 77
STATUS = {0: "ok", 1: "degraded", 2: "lost"}


def expected_lines(samples, log):
    """The example's output for the log's first robot, from C++'s decoding."""
    out = subprocess.run([samples, log], check=True, capture_output=True, text=True).stdout
    poses = [json.loads(line)["fields"] for line in out.splitlines()
             if json.loads(line)["channel"] == "POSE_FUSED"]
    if not poses:
        raise SystemExit(f"FAIL: {log} has no POSE_FUSED")
    robot = poses[0]["robot_id"]
    lines = []
    for p in poses:
        if p["robot_id"] != robot:
            continue
        x, y, h = (v if v is not None else math.nan for v in (p["x_m"], p["y_m"], p["heading_rad"]))
        lines.append(f"{p['utime']} {x:.4f} {y:.4f} {math.degrees(h):.1f} {STATUS[p['status']]}")
    return robot, lines


def check_doc_shows(source, example):
    """docs/python.md holds the example's code verbatim (after its docstring)."""
    with open(os.path.join(source, "docs", "examples", example)) as f:
        code = f.read()
    body = code.split('"""', 2)[2].strip()
    with open(os.path.join(source, "docs", "python.md")) as f:
        doc = f.read()
    if body not in doc:
        print(f"FAIL: docs/python.md does not show docs/examples/{example} as the file has it")
        return False
    return True


def compare(got, want, what):
    if got == want:
        print(f"{what}: {len(got)} poses, as decoded by C++")
        return True
    print(f"FAIL: {what}: {len(got)} lines, {len(want)} expected")
    for i, (a, b) in enumerate(zip(got, want)):
        if a != b:
            print(f"  first difference at line {i}: got '{a}', expected '{b}'")
            break
    return False


def run_pipe(args, robot, want):
    example = os.path.join(args.source, "docs", "examples", "follow_pose_listen.py")
    command = (f"set -o pipefail; '{args.roomfix}' listen --lcm-url 'file://{args.log}?speed=0' "
               f"--channel POSE_FUSED | python3 '{example}' --robot {robot}")
    run = subprocess.run(["bash", "-c", command], capture_output=True, text=True, timeout=60)
    if run.returncode != 0:
        print(f"FAIL: the pipe exited {run.returncode}: {run.stderr}")
        return 1
    return 0 if compare(run.stdout.splitlines(), want, "roomfix listen | follow_pose_listen.py") else 1


def run_lcm(args, robot, want):
    path = [d for d in (args.lcm_python_dir, args.python_dir) if d]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(path + [os.environ.get("PYTHONPATH", "")]))
    probe = subprocess.run(["python3", "-c", "import lcm"], env=env, capture_output=True, text=True)
    if probe.returncode != 0:
        print("SKIP: LCM's Python module is not importable (Debian 12 does not package it; "
              "pip install lcm, or build LCM 1.5 and configure with "
              "-DROOMFIX_LCM_PYTHON_DIR=<its build>/python; docs/python.md): "
              + probe.stderr.strip().splitlines()[-1])
        return SKIP
    player = shutil.which("lcm-logplayer")
    if player is None:
        print("SKIP: no lcm-logplayer (apt-get install liblcm-bin)")
        return SKIP
    example = os.path.join(args.source, "docs", "examples", "follow_pose_lcm.py")
    follower = subprocess.Popen(
        ["python3", example, "--robot", str(robot), "--count", str(len(want))], env=env,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # The player starts once the example has subscribed (its first stderr line).
    ready = follower.stderr.readline()
    if "following robot" not in ready:
        follower.kill()
        print(f"FAIL: follow_pose_lcm.py did not start: {ready}{follower.stderr.read()}")
        return 1
    errors = []
    drain = threading.Thread(target=lambda: errors.extend(follower.stderr), daemon=True)
    drain.start()
    subprocess.run([player, args.log], check=True, capture_output=True, timeout=120)
    try:
        out, _ = follower.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        follower.kill()
        out, _ = follower.communicate()
        print(f"FAIL: follow_pose_lcm.py still waiting after the log ended; it printed "
              f"{len(out.splitlines())} of {len(want)} poses; stderr: {''.join(errors)}")
        return 1
    if follower.returncode != 0:
        print(f"FAIL: follow_pose_lcm.py exited {follower.returncode}: {''.join(errors)}")
        return 1
    return 0 if compare(out.splitlines(), want, "lcm-logplayer -> follow_pose_lcm.py") else 1


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("mode", choices=["pipe", "lcm"])
    p.add_argument("--samples", required=True)
    p.add_argument("--roomfix", required=True)
    p.add_argument("--python-dir", required=True)
    p.add_argument("--source", required=True)
    p.add_argument("--log", required=True)
    p.add_argument("--lcm-python-dir", default="")
    args = p.parse_args()
    example = "follow_pose_listen.py" if args.mode == "pipe" else "follow_pose_lcm.py"
    doc_ok = check_doc_shows(args.source, example)
    robot, want = expected_lines(args.samples, args.log)
    code = run_pipe(args, robot, want) if args.mode == "pipe" else run_lcm(args, robot, want)
    if code == SKIP:
        return SKIP
    return 1 if code != 0 or not doc_ok else 0


if __name__ == "__main__":
    sys.exit(main())
