#!/usr/bin/python3
# comp_probe.py - the [DISPLAY] DISPLAY program of the configuration that
# run-linuxcnc generates. LinuxCNC starts it in the foreground as
#     comp_probe.py -ini /tmp/machine.ini
# once task, motion and io are up, and shuts everything down when it exits,
# passing its exit code through.
#
# It must run with Debian's /usr/bin/python3: the `linuxcnc` and `hal` modules
# live in /usr/lib/python3/dist-packages.
#
# What it does: estop reset, machine on, home (immediate: HOME_SEARCH_VEL 0),
# MDI mode, then for each target of moves.txt an MDI `G90 G21 G1 X.. F..`,
# waits until the interpreter is idle, motion is in position, backlash-vel is
# 0 and two HAL snapshots 20 ms apart agree, and records joint 0's pins.
# Result: result.json beside the INI (written also on failure, with "error").
#
# Exit codes (run-linuxcnc maps them, see README.md):
#   0 ok, 3 LinuxCNC never became ready, 5 a move timed out or failed,
#   1 anything else.

import json
import os
import sys
import time
import traceback

import hal
import linuxcnc

EXIT_OK, EXIT_OTHER, EXIT_NOT_READY, EXIT_MOVE = 0, 1, 3, 5

PINS = {
    "pos_cmd_mm": "joint.0.pos-cmd",
    "backlash_corr_mm": "joint.0.backlash-corr",
    "backlash_filt_mm": "joint.0.backlash-filt",
    "motor_pos_cmd_mm": "joint.0.motor-pos-cmd",
}
RAMP_VEL_PIN = "joint.0.backlash-vel"


class ProbeError(Exception):
    def __init__(self, kind, code, message):
        super().__init__(message)
        self.kind = kind
        self.code = code


def snapshot():
    snap = {key: float(hal.get_value(pin)) for key, pin in PINS.items()}
    snap["backlash_vel_mm_per_s"] = float(hal.get_value(RAMP_VEL_PIN))
    return snap


class Probe:
    def __init__(self, ini_path):
        self.ini_path = ini_path
        self.work = os.path.dirname(os.path.abspath(ini_path))
        ini = linuxcnc.ini(ini_path)
        self.feed = float(ini.find("MTCAL", "FEED_MM_PER_MIN") or 30000)
        self.ready_timeout = float(ini.find("MTCAL", "READY_TIMEOUT_S") or 30)
        self.move_timeout = float(ini.find("MTCAL", "MOVE_TIMEOUT_S") or 30)
        self.settle_timeout = float(ini.find("MTCAL", "SETTLE_TIMEOUT_S") or 10)
        self.moves_file = os.path.join(self.work, ini.find("MTCAL", "MOVES") or "moves.txt")
        self.result_file = os.path.join(self.work, ini.find("MTCAL", "RESULT") or "result.json")
        self.messages = []  # everything LinuxCNC's error channel said
        self.stops = []
        self.home_snapshot = None
        self.s = None
        self.c = None
        self.e = None

    # --- LinuxCNC plumbing -------------------------------------------------
    def drain_errors(self):
        if self.e is None:
            return
        while True:
            msg = self.e.poll()
            if not msg:
                return
            kind, text = msg
            if kind in (linuxcnc.NML_ERROR, linuxcnc.OPERATOR_ERROR):
                level = "error"
            elif kind in (linuxcnc.NML_TEXT, linuxcnc.OPERATOR_TEXT):
                level = "text"
            else:
                level = "display"
            self.messages.append({"level": level, "text": text.strip()})

    def poll(self):
        self.s.poll()
        self.drain_errors()
        return self.s

    def wait_for(self, what, predicate, timeout, kind, code):
        deadline = time.monotonic() + timeout
        while True:
            s = self.poll()
            if predicate(s):
                return
            if time.monotonic() > deadline:
                raise ProbeError(kind, code, "timed out after %g s waiting for %s" % (timeout, what))
            time.sleep(0.005)

    def connect(self):
        deadline = time.monotonic() + self.ready_timeout
        last = None
        while True:
            try:
                self.s = linuxcnc.stat()
                self.c = linuxcnc.command()
                self.e = linuxcnc.error_channel()
                self.s.poll()
                break
            except linuxcnc.error as exc:  # NML channels not there yet
                last = exc
            if time.monotonic() > deadline:
                raise ProbeError("not_ready", EXIT_NOT_READY,
                                 "LinuxCNC's NML channels never opened: %s" % last)
            time.sleep(0.1)
        self.drain_errors()

    def machine_on_and_home(self):
        c = self.c
        self.wait_for("task to report ESTOP state",
                      lambda s: s.task_state in (linuxcnc.STATE_ESTOP, linuxcnc.STATE_ESTOP_RESET,
                                                 linuxcnc.STATE_OFF, linuxcnc.STATE_ON),
                      self.ready_timeout, "not_ready", EXIT_NOT_READY)
        c.state(linuxcnc.STATE_ESTOP_RESET)
        self.wait_for("estop reset", lambda s: s.task_state == linuxcnc.STATE_ESTOP_RESET,
                      self.ready_timeout, "not_ready", EXIT_NOT_READY)
        c.state(linuxcnc.STATE_ON)
        self.wait_for("machine on", lambda s: s.task_state == linuxcnc.STATE_ON,
                      self.ready_timeout, "not_ready", EXIT_NOT_READY)
        c.mode(linuxcnc.MODE_MANUAL)
        c.wait_complete(self.ready_timeout)
        c.home(-1)
        self.wait_for("homing of joint 0", lambda s: s.homed[0] == 1,
                      self.ready_timeout, "not_ready", EXIT_NOT_READY)
        c.mode(linuxcnc.MODE_MDI)
        c.wait_complete(self.ready_timeout)
        self.wait_for("MDI mode", lambda s: s.task_mode == linuxcnc.MODE_MDI,
                      self.ready_timeout, "not_ready", EXIT_NOT_READY)

    def settle(self, what):
        """Wait until motion is done and joint 0's pins are still; return the snapshot."""
        self.wait_for(what + ": interpreter idle and in position",
                      lambda s: (s.interp_state == linuxcnc.INTERP_IDLE and s.inpos
                                 and s.queue == 0 and s.state != linuxcnc.RCS_EXEC),
                      self.move_timeout, "move_timeout", EXIT_MOVE)
        deadline = time.monotonic() + self.settle_timeout
        t0 = time.monotonic()
        prev = snapshot()
        while True:
            time.sleep(0.020)
            cur = snapshot()
            # backlash-vel is 0 both when the filter has arrived and when it has
            # stalled (the ramp bug): either way nothing changes any more.
            if cur == prev and cur["backlash_vel_mm_per_s"] == 0.0:
                cur["settle_s"] = time.monotonic() - t0
                return cur
            if time.monotonic() > deadline:
                raise ProbeError("move_timeout", EXIT_MOVE,
                                 "%s: joint 0 did not come to rest within %g s (last %r)"
                                 % (what, self.settle_timeout, cur))
            prev = cur

    def run_moves(self, targets):
        s = self.poll()
        if s.task_state != linuxcnc.STATE_ON:
            raise ProbeError("not_ready", EXIT_NOT_READY, "machine is not on")
        previous = self.home_snapshot["pos_cmd_mm"]
        for index, (line_no, text, target) in enumerate(targets):
            cmd = "G90 G21 G1 X%s F%s" % (format(target, ".12f"), format(self.feed, ".6f"))
            errors_before = sum(1 for m in self.messages if m["level"] == "error")
            t0 = time.monotonic()
            self.c.mdi(cmd)
            self.c.wait_complete(self.move_timeout)
            snap = self.settle("move %d (moves line %d: %s)" % (index, line_no, text))
            new_errors = [m["text"] for m in self.messages if m["level"] == "error"][errors_before:]
            if new_errors:
                raise ProbeError("move_failed", EXIT_MOVE,
                                 "move %d (%s) -> LinuxCNC error: %s" % (index, cmd, "; ".join(new_errors)))
            direction = 1 if target > previous else (-1 if target < previous else 0)
            stop = {
                "index": index,
                "moves_line": line_no,
                "target_mm": target,
                "direction": direction,
                "from_mm": previous,
                "pos_cmd_mm": snap["pos_cmd_mm"],
                "backlash_corr_mm": snap["backlash_corr_mm"],
                "backlash_filt_mm": snap["backlash_filt_mm"],
                "motor_pos_cmd_mm": snap["motor_pos_cmd_mm"],
                "motor_minus_pos_cmd_mm": snap["motor_pos_cmd_mm"] - snap["pos_cmd_mm"],
                "move_s": time.monotonic() - t0,
            }
            self.stops.append(stop)
            self.write_result()  # progress: a killed run still shows its stops
            previous = snap["pos_cmd_mm"]

    def write_result(self, error=None):
        doc = {
            "linuxcnc_version": getattr(linuxcnc, "version", "unknown"),
            "home": self.home_snapshot,
            "stops": self.stops,
            "messages": self.messages,
        }
        if error is not None:
            doc["error"] = {"kind": error[0], "message": error[1]}
        tmp = self.result_file + ".part"
        with open(tmp, "w") as f:
            json.dump(doc, f, indent=1)
            f.write("\n")
        os.replace(tmp, self.result_file)


def read_moves(path):
    targets = []
    with open(path) as f:
        for line_no, line in enumerate(f, 1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            targets.append((line_no, text, float(text)))
    return targets


def main(argv):
    if "-ini" not in argv:
        print("comp_probe.py: usage: comp_probe.py -ini FILE (run by linuxcnc)", file=sys.stderr)
        return EXIT_OTHER
    probe = Probe(argv[argv.index("-ini") + 1])
    comp = None
    try:
        targets = read_moves(probe.moves_file)
        comp = hal.component("mtcal-comp-probe")  # hal.get_value needs a ready component
        comp.ready()
        probe.connect()
        probe.machine_on_and_home()
        time.sleep(0.05)
        probe.home_snapshot = probe.settle("after homing")
        probe.run_moves(targets)
        # LinuxCNC may report comp-table problems at any time before this point
        time.sleep(0.05)
        probe.drain_errors()
        probe.write_result()
        return EXIT_OK
    except ProbeError as exc:
        print("comp_probe.py: %s" % exc, file=sys.stderr)
        try:
            probe.drain_errors()
        except Exception:
            pass
        probe.write_result((exc.kind, str(exc)))
        return exc.code
    except Exception as exc:  # keep the partial result and say what broke
        traceback.print_exc()
        probe.write_result(("internal", "%s: %s" % (type(exc).__name__, exc)))
        return EXIT_OTHER
    finally:
        if comp is not None:
            try:
                comp.exit()
            except Exception:
                pass


if __name__ == "__main__":
    sys.exit(main(sys.argv))
