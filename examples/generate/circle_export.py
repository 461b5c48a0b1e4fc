#!/usr/bin/env python3
"""Writes examples/circle/xy_r100_export.csv: a circular test as another program exports it.

XY plane, radius 100 mm, feed 1000 mm/min, one point per 0.5 deg each way (CCW from 0.25 deg
up, then CW from 359.75 deg down), the radial deviation in um to first order (the projection
of the tool's error on the radial direction) of these known errors:

  squareness +25 urad     x error = -25e-6 y
  servo mismatch +0.8 ms  X lags 0.8 ms more than Y: +-(F dtau / 2) sin 2t, + CCW
  lost motion X 2.0 um, Y 3.0 um
                          each axis -s b (min(d / b, 1) - 1/2), s its direction of motion,
                          d its travel since its last reversal: the table stays behind the
                          motor until the motor has crossed the play b
  centre offset (4, -3) um
  noise                   Python's random.gauss(0, 0.1 um), random.seed(4), one draw per
                          point in file order

Only the standard library: the noise is Python's own Mersenne Twister (random).

Usage: circle_export.py OUT_DIR    (writes OUT_DIR/circle/xy_r100_export.csv)
"""
import math
import os
import random
import sys

RADIUS_MM = 100.0
POINTS_PER_DIRECTION = 720
FEED_MM_PER_MIN = 1000.0
SQUARENESS_RAD = 25e-6
SERVO_MISMATCH_S = 0.0008
LOST_MOTION_X_UM = 2.0
LOST_MOTION_Y_UM = 3.0
CENTRE_UM = (4.0, -3.0)
NOISE_UM = 0.1
SEED = 4

HEADER = """\
# mtcal example: a circular test as another program exports it (XY, radius 100 mm, feed 1000 mm/min,
# one point per 0.5 deg each way). Made from known errors, first order: squareness +25 urad
# (x error = -25e-6 y), servo mismatch +0.8 ms, lost motion X 2.0 um and Y 3.0 um (play of the
# table behind the motor), centre offset (4, -3) um, noise 0.1 um. See docs/ballbar.md.
angle_deg,direction,deviation_um
"""


def lost_motion_um(play_um, angle_since_reversal, direction):
    """An axis' error after its reversal: its travel since is R (1 - cos) of the angle turned."""
    travel_um = RADIUS_MM * (1 - math.cos(angle_since_reversal)) * 1000
    return -direction * play_um * (min(travel_um / play_um, 1) - 0.5)


def rows():
    random.seed(SEED)
    for sense in (1, -1):  # CCW, then CW
        for i in range(POINTS_PER_DIRECTION):
            k = i + 0.5 if sense > 0 else POINTS_PER_DIRECTION - i - 0.5
            t = 2 * math.pi * k / POINTS_PER_DIRECTION
            cos_t, sin_t = math.cos(t), math.sin(t)
            y_mm = RADIUS_MM * sin_t
            ex_um = -SQUARENESS_RAD * y_mm * 1000 + CENTRE_UM[0]
            ey_um = CENTRE_UM[1]
            # x = R cos t reverses at 0 and 180 deg, y = R sin t at 90 and 270 deg.
            x_direction = -1 if sense * sin_t > 0 else 1
            y_direction = 1 if sense * cos_t > 0 else -1
            ex_um += lost_motion_um(LOST_MOTION_X_UM, (sense * t) % math.pi, x_direction)
            ey_um += lost_motion_um(LOST_MOTION_Y_UM, (sense * (t - math.pi / 2)) % math.pi, y_direction)
            servo_um = sense * (FEED_MM_PER_MIN / 60) * SERVO_MISMATCH_S / 2 * 1000 * math.sin(2 * t)
            deviation_um = cos_t * ex_um + sin_t * ey_um + servo_um
            deviation_um += random.gauss(0, NOISE_UM)
            yield "%.3f,%s,%.3f\n" % (math.degrees(t), "ccw" if sense > 0 else "cw", deviation_um)


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: circle_export.py OUT_DIR")
    directory = os.path.join(sys.argv[1], "circle")
    os.makedirs(directory, exist_ok=True)
    with open(os.path.join(directory, "xy_r100_export.csv"), "w", newline="\n") as f:
        f.write(HEADER)
        f.writelines(rows())


if __name__ == "__main__":
    main()
