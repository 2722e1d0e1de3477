"""A robot's program reading distances from Stereo GUI's pipeline (the Python API).

Runs as it is on the simulated rig (no cameras, no calibration file needed):

    .venv/bin/python examples/robot_reader.py
    .venv/bin/python examples/robot_reader.py --source cams:0,1 --calib calib.yaml

It reads 30 frames, says the distance at the centre of the picture with its +- (as a
double-click in the window reads it), and watches a box in front of the robot with an alarm.
"""

from __future__ import annotations

import argparse
import sys

import stereo_gui
from stereo_gui.core.errors import StereoGuiError


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--source", default="sim:wall:rig:1.5", help="as stereo-gui --source")
    p.add_argument("--calib", help="calibration file (the simulated rig: its true calibration)")
    p.add_argument("--preset", default="live")
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--alarm-m", type=float, default=1.0, help="alarm below this distance")
    args = p.parse_args()
    try:
        with stereo_gui.open_rig(args.source, args.calib, args.preset) as rig:
            print(f"opened {rig.description}")
            for frame in rig.frames(limit=args.frames):  # the newest frame each time
                w, h = frame.calibration.image_size
                centre = frame.measure(w // 2, h // 2)
                box = frame.nearest(region=(w // 2 - 60, h // 2 - 60, 120, 120),
                                    alarm_mm=1000.0 * args.alarm_m)
                alarm = "ALARM" if box.alarm else "clear"
                print(f"frame {frame.index}: centre {centre}; box nearest "
                      f"{box.nearest_mm / 1000:.3f} m ({alarm}); "
                      f"{(frame.depth_mm > 0).mean():.0%} of the picture has depth")
            print(f"{rig.dropped_frames} frames skipped for newer ones")
    except StereoGuiError as exc:
        print(f"robot_reader: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
