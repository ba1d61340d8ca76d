#!/usr/bin/env python3
"""Runs docs/export.md's pandas example on a real export.

Exports the log with `roomfix export LOG --csv DIR`, takes the first
```python block under "## pandas" in docs/export.md, points its `csv`
folder at DIR and runs it: the documented reading code must work on the
files roomfix writes. Exits 77 (skipped), saying so, without pandas.
"""
import argparse
import os
import subprocess
import sys
import tempfile

SKIP = 77


def doc_block(source):
    with open(os.path.join(source, "docs", "export.md")) as f:
        text = f.read()
    section = text.split("\n## pandas\n", 1)[1]
    return section.split("```python\n", 1)[1].split("```", 1)[0]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--roomfix", required=True)
    p.add_argument("--source", required=True)
    p.add_argument("--log", required=True)
    args = p.parse_args()
    # This python3, else Debian's (python3-pandas installs for that one).
    python = next((p for p in (sys.executable, "/usr/bin/python3")
                   if os.path.exists(p) and
                   subprocess.run([p, "-c", "import pandas"], capture_output=True).returncode == 0),
                  None)
    if python is None:
        print("SKIP: pandas is not installed for python3 (apt-get install python3-pandas)")
        return SKIP
    code = doc_block(args.source)
    folder_line = 'csv = "build/demo/csv"'
    if folder_line not in code:
        print(f"FAIL: the pandas example no longer sets {folder_line}")
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        folder = os.path.join(tmp, "csv")
        subprocess.run([args.roomfix, "export", args.log, "--csv", folder], check=True,
                       capture_output=True)
        run = subprocess.run([python, "-c", code.replace(folder_line, f"csv = {folder!r}")],
                             capture_output=True, text=True)
    if run.returncode != 0:
        print(f"FAIL: docs/export.md's pandas example: {run.stderr}")
        return 1
    print(run.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
