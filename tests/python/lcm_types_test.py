#!/usr/bin/env python3
"""The Python message types (lcm-gen --python, docs/python.md) against C++.

roomfix_lcm_samples prints messages as the C++ side encodes them (a sample
of every type, nested types on their own too, then every roomfix event of
the recorded logs) with every field as C++ decoded it. Each must:
  - decode with the generated Python class of its type to the same fields,
    exactly (doubles bit for bit, NaN as NaN, strings as UTF-8);
  - have the same fingerprint in Python as C++'s getHash();
  - be refused by the Python decode (ValueError) when its fingerprint is
    another type's, which is what protects a Python reader on the bus;
  - encode back from Python to the same bytes.
Every .lcm file of lcmtypes/ must be covered, and the package must export
every type (`from roomfix import pose2d_t`).
"""
import argparse
import glob
import importlib
import json
import math
import os
import subprocess
import sys


def compare(py, want, path, errors):
    """Appends to errors every difference between a decoded value and C++'s."""
    if hasattr(py, "__slots__"):
        if not isinstance(want, dict):
            errors.append(f"{path}: C++ gave {want!r} for a struct")
            return
        slots = set(py.__slots__)
        if slots != set(want):
            errors.append(f"{path}: Python fields {sorted(slots)} but C++ fields {sorted(want)}")
        for name in slots & set(want):
            compare(getattr(py, name), want[name], f"{path}.{name}", errors)
    elif isinstance(py, (bytes, bytearray)):
        if list(py) != want:
            errors.append(f"{path}: bytes {list(py)[:16]}... != {want[:16] if want else want}...")
    elif isinstance(py, (list, tuple)):
        if not isinstance(want, list) or len(py) != len(want):
            errors.append(f"{path}: {len(py)} items, C++ {want!r}")
            return
        for i, (a, b) in enumerate(zip(py, want)):
            compare(a, b, f"{path}[{i}]", errors)
    elif isinstance(py, float):
        # C++ printed the shortest form that reads back to the same double
        # (nlohmann's dump()); NaN and infinities as null. (-0.0 == 0.0 here:
        # the sign of a zero is checked by the re-encoding, bit for bit.)
        same = not math.isfinite(py) if want is None else (
            isinstance(want, (int, float)) and not isinstance(want, bool) and py == want)
        if not same:
            errors.append(f"{path}: {py!r} != {want!r}")
    elif isinstance(py, bool) or not isinstance(py, (int, str)):
        errors.append(f"{path}: unexpected Python value {py!r}")
    elif py != want or type(py) is not type(want):
        errors.append(f"{path}: {py!r} != {want!r}")


def check_line(line, roomfix, errors):
    """Checks one message; returns its type's bare name."""
    sample = json.loads(line)
    name = sample["type"].split(".", 1)[1]
    cls = getattr(roomfix, name)
    where = f"{sample['origin']} ({name})"
    data = bytes.fromhex(sample["hex"])
    fingerprint = cls._get_packed_fingerprint()
    if fingerprint.hex() != sample["fingerprint"]:
        errors.append(f"{where}: Python fingerprint {fingerprint.hex()} != C++ {sample['fingerprint']}")
    if data[:8] != fingerprint:
        errors.append(f"{where}: the bytes start with {data[:8].hex()}, not the fingerprint")
    msg = cls.decode(data)
    compare(msg, sample["fields"], where, errors)
    if msg.encode() != data:
        errors.append(f"{where}: Python re-encodes {len(msg.encode())} other bytes")
    wrong = bytes([data[0] ^ 0x01]) + data[1:]
    try:
        cls.decode(wrong)
        errors.append(f"{where}: decoded with a wrong fingerprint")
    except ValueError:
        pass
    return name


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--samples", required=True, help="the roomfix_lcm_samples binary")
    p.add_argument("--python-dir", required=True, help="the generated package's parent (build/python)")
    p.add_argument("--source", required=True, help="the source tree (for lcmtypes/*.lcm)")
    p.add_argument("--log", action="append", default=[], help="a recorded log to decode too")
    args = p.parse_args()

    sys.path.insert(0, args.python_dir)
    roomfix = importlib.import_module("roomfix")
    where = os.path.dirname(roomfix.__file__)
    if os.path.realpath(where) != os.path.realpath(os.path.join(args.python_dir, "roomfix")):
        print(f"FAIL: imported roomfix from {where}, not the build's {args.python_dir}")
        return 1

    out = subprocess.run([args.samples] + args.log, check=True, capture_output=True, text=True)
    errors = []
    seen = {}
    for line in out.stdout.splitlines():
        name = check_line(line, roomfix, errors)
        seen[name] = seen.get(name, 0) + 1

    lcm_types = sorted(os.path.basename(f)[:-4]
                       for f in glob.glob(os.path.join(args.source, "lcmtypes", "*.lcm")))
    for name in lcm_types:
        if name not in seen:
            errors.append(f"{name}: no message of this type was checked (add a sample to "
                          "tests/python/lcm_samples.cc)")
        if not hasattr(roomfix, name):
            errors.append(f"{name}: `from roomfix import {name}` fails")
    for e in errors[:50]:
        print("FAIL:", e)
    if errors:
        print(f"{len(errors)} differences")
        return 1
    print("decoded in Python as in C++: " +
          ", ".join(f"{name} {count}" for name, count in sorted(seen.items())))
    return 0


if __name__ == "__main__":
    sys.exit(main())
