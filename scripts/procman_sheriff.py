#!/usr/bin/env python3
"""One headless sheriff from start to stop, for scripts/procman_check.

    procman_sheriff.py PMD START_SCRIPT STOP_SCRIPT --seconds N [--kill CMD]

libbot2's own headless sheriff (bot-procman-sheriff --no-gui) runs one script
and cannot be told to run another, so it cannot stop what it started
(docs/procman.md). This drives the same sheriff, libbot2's
bot_procman.sheriff.Sheriff on its GLib loop exactly as sheriff_gtk.py does,
through both scripts: it loads PMD, runs START_SCRIPT, waits until every
command the script started reports Running with a pid, kills CMD with
SIGKILL and waits for the deputy to respawn it under a new pid, lets the
system run for N seconds, runs STOP_SCRIPT, and checks every command
stopped. It prints one line per check ("ok: ..." or "FAIL: ...") and exits
0 when all passed. Needs PYTHONPATH with bot_procman and LCM's lcm module
(the paths bot-procman-sheriff sets).
"""

import argparse
import os
import signal
import sys
import time

import lcm
from gi.repository import GLib

from bot_procman import sheriff as sheriff_mod
from bot_procman import sheriff_config
from bot_procman.printf_t import printf_t

RUNNING = sheriff_mod.RUNNING
STOPPED = (sheriff_mod.STOPPED_OK, sheriff_mod.STOPPED_ERROR)
# How long a step may take: start_demo waits for each group to run (a few
# seconds), a respawn takes the deputy 10 ms to 1 s, stop_demo's logger
# has stop_time_allowed 10 s.
STEP_TIMEOUT_S = 30.0


class Check(object):
    def __init__(self):
        self.failed = False

    def __call__(self, passed, text):
        print(("  ok: " if passed else "FAIL: ") + text, flush=True)
        self.failed = self.failed or not passed
        return passed


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("pmd")
    parser.add_argument("start_script")
    parser.add_argument("stop_script")
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--kill", default="", help="command to SIGKILL once running")
    parser.add_argument("--printf-log", default="",
                        help="write the commands' output (PMD_PRINTF) to this file")
    args = parser.parse_args()
    check = Check()

    lc = lcm.LCM()
    sheriff = sheriff_mod.Sheriff(lc)
    sheriff.load_config(sheriff_config.config_from_filename(args.pmd), False)
    if args.printf_log:
        # What the sheriff's window shows in its console: each command's
        # output as the deputy forwards it.
        printf_log = open(args.printf_log, "w")
        ids = {}

        def on_printf(_, data):
            msg = printf_t.decode(data)
            if msg.sheriff_id not in ids:
                cmd = sheriff.get_command_by_sheriff_id(msg.sheriff_id)
                ids[msg.sheriff_id] = cmd.command_id if cmd else str(msg.sheriff_id)
            printf_log.write("".join("%s: %s\n" % (ids[msg.sheriff_id], line)
                                     for line in msg.text.splitlines() if line))
            printf_log.flush()
        lc.subscribe("PMD_PRINTF", on_printf)
    loop = GLib.MainLoop()
    GLib.io_add_watch(lc, GLib.IOCondition.IN, lambda *_: lc.handle() or True)
    GLib.timeout_add(1000, lambda *_: sheriff.send_orders() or True)
    finished = []

    # libbot2's Signal holds its slots weakly: a lambda would be collected
    # at once and never called; this function lives as long as main.
    def on_script_finished(script):
        finished.append(script.name)
    sheriff.script_finished.connect(on_script_finished)

    def spin_until(done, timeout_s):
        """Runs the loop until done() or the timeout; True when done."""
        give_up = time.monotonic() + timeout_s
        context = loop.get_context()
        while not done() and time.monotonic() < give_up:
            context.iteration(False) or time.sleep(0.01)
        return done()

    def run_script(name):
        script = sheriff.get_script(name)
        if not check(script is not None, "the configuration has script %s" % name):
            return False
        errors = sheriff.execute_script(script)
        if not check(not errors, "%s accepted%s" % (name, "".join("; " + e for e in errors or []))):
            return False
        started = time.monotonic()
        done = spin_until(lambda: name in finished, STEP_TIMEOUT_S)
        return check(done, "script %s finished in %.1f s" % (name, time.monotonic() - started))

    # The deputy's first report: the sheriff has no commands' states before.
    check(spin_until(lambda: sheriff.get_deputies(), STEP_TIMEOUT_S),
          "a deputy answered: %s" % ", ".join(d.name for d in sheriff.get_deputies()))
    commands = {c.command_id: c for c in sheriff.get_all_commands()}
    if not run_script(args.start_script):
        return 1
    running = lambda: [c for c in commands.values() if c.status() == RUNNING and c.pid > 0]
    spin_until(lambda: len(running()) == len(
        [c for c in commands.values() if c.desired_runid != 0]), 5)
    for c in sorted(commands.values(), key=lambda c: c.command_id):
        print("     %-16s %-20s pid %d" % (c.command_id, c.status(), c.pid), flush=True)
    started = [c for c in commands.values() if c.desired_runid != 0]
    check(len(running()) == len(started) and started,
          "%d of the %d commands %s started are running" % (len(running()), len(started),
                                                            args.start_script))

    if args.kill:
        victim = commands.get(args.kill)
        if check(victim is not None and victim.pid > 0, "%s is running" % args.kill):
            old_pid = victim.pid
            os.kill(old_pid, signal.SIGKILL)
            killed = time.monotonic()
            back = spin_until(lambda: victim.pid > 0 and victim.pid != old_pid
                              and victim.status() == RUNNING, STEP_TIMEOUT_S)
            check(back, "kill -9 %s (pid %d): respawned by the deputy as pid %d, seen by "
                  "the sheriff %.2f s later" % (args.kill, old_pid, victim.pid,
                                                time.monotonic() - killed))

    print("     running for %.0f s" % args.seconds, flush=True)
    spin_until(lambda: False, args.seconds)
    still = [c.command_id for c in started if c.status() != RUNNING]
    check(not still, "after %.0f s every started command still runs%s"
          % (args.seconds, (": not " + ", ".join(still)) if still else ""))

    if not run_script(args.stop_script):
        return 1
    spin_until(lambda: all(c.status() in STOPPED for c in commands.values()), 5)
    for c in sorted(commands.values(), key=lambda c: c.command_id):
        print("     %-16s %-20s exit code %d" % (c.command_id, c.status(), c.exit_code),
              flush=True)
    errors = [c.command_id for c in started
              if c.status() != sheriff_mod.STOPPED_OK or c.exit_code != 0]
    check(not errors, "%s stopped every command with exit code 0%s"
          % (args.stop_script, (": not " + ", ".join(errors)) if errors else ""))
    return 1 if check.failed else 0


if __name__ == "__main__":
    sys.exit(main())
