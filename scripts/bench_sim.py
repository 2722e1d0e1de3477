"""Benchmark and accuracy figures of the simulated rig (a script, not a test).

Usage: python scripts/bench_sim.py [--pairs N]
Prints: ray-map build time, rendering time per pair (board, scene, board in front of the demo
scene, at supersample 3 and 2), corner agreement with cv2.projectPoints (px RMS), and fx /
baseline recovered by a quick OpenCV calibration on rendered pairs.
"""

from __future__ import annotations

import argparse
import time

import cv2
import numpy as np

from stereo_gui.core.detect import detect_board
from stereo_gui.sources.sim import RigConfig, Scene, SimRig, SimSource


def _ms(fn, n: int) -> float:
    fn()
    t = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t) / n * 1000.0


def _detect(img, board):
    found = detect_board(img, board)  # the application's detector
    return None if found is None else found.corners


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pairs", type=int, default=20)
    ap.add_argument("--seed", type=int, default=123)
    args = ap.parse_args()
    for s in (3, 2):
        t = time.perf_counter()
        rig = SimRig(RigConfig(supersample=s), seed=args.seed)
        print(f"supersample {s}: ray maps built in {time.perf_counter() - t:.2f} s")
        poses = rig.board_poses(30)
        rng = np.random.default_rng(0)
        it = iter(range(10**9))
        demo = Scene.demo()
        rig.render_scene(demo, rng)
        print(f"  board pair          {_ms(lambda: rig.render_board_pair(poses[next(it) % 30], rng), 30):6.1f} ms")
        print(f"  demo scene pair     {_ms(lambda: rig.render_scene(demo, rng), 30):6.1f} ms")
        print(f"  board + demo scene  {_ms(lambda: rig.render_board_pair(poses[next(it) % 30], rng, scene=demo), 30):6.1f} ms")
        src = SimSource(rig, paced=False)
        print(f"  SimSource.read()    {_ms(src.read, 60):6.1f} ms (mixed, unpaced)")

    rig = SimRig(seed=args.seed)
    board = rig.config.board
    obj, pl, pr, sq = [], [], [], []
    for pose, (left, right) in zip(rig.board_poses(args.pairs), rig.calibration_set(args.pairs)):
        found = []
        for cam, img in ((0, left), (1, right)):
            c = _detect(img, board)
            if c is None:
                break
            truth = rig.project(pose.corners_left_mm(board), cam)
            if np.sum((c[::-1] - truth) ** 2) < np.sum((c - truth) ** 2):
                c = c[::-1]
            sq.append(np.sum((c - truth) ** 2, 1))
            found.append(c.astype(np.float32))
        if len(found) == 2:
            obj.append(board.object_points_mm())
            pl.append(found[0])
            pr.append(found[1])
    print(f"corner agreement with cv2.projectPoints: {np.sqrt(np.mean(np.concatenate(sq))):.3f} px RMS "
          f"over {len(sq)} images")
    size = rig.config.image_size
    _, M1, D1, _, _ = cv2.calibrateCamera(obj, pl, size, None, None)
    _, M2, D2, _, _ = cv2.calibrateCamera(obj, pr, size, None, None)
    rms, M1, D1, M2, D2, R, T, _, _ = cv2.stereoCalibrate(obj, pl, pr, M1, D1, M2, D2, size,
                                                          flags=cv2.CALIB_FIX_INTRINSIC)
    t = rig.truth
    print(f"quick calibration on {len(obj)} pairs: stereo RMS {rms:.3f} px")
    print(f"  fx left  {M1[0, 0]:.2f} (true {t.M1[0, 0]:.2f}, {100 * (M1[0, 0] / t.M1[0, 0] - 1):+.3f} %)")
    print(f"  fx right {M2[0, 0]:.2f} (true {t.M2[0, 0]:.2f}, {100 * (M2[0, 0] / t.M2[0, 0] - 1):+.3f} %)")
    b = float(np.linalg.norm(T))
    print(f"  baseline {b:.2f} mm (true {t.baseline_mm:.2f}, {100 * (b / t.baseline_mm - 1):+.3f} %)")


if __name__ == "__main__":
    main()
