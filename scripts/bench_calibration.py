"""Time chessboard detection + stereo calibration of N simulated-rig pairs (and the real webcam set).

    python scripts/bench_calibration.py [--pairs 50] [--seed 5] [--real ../shared/data/real-webcam-9x6-30mm]

Prints seconds per stage, compares the thread pool with serial detection and a process pool, the
classic and SB detectors, and the report's fixed-intrinsics stereo step with the joint refinement
against the rig's truth (errors in percent).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.calibrate import calibrate_stereo
from stereo_gui.core.detect import PairInput, detect_pair, detect_pairs
from stereo_gui.files.pairs import discover_pairs, load_image
from stereo_gui.sources.sim import RigTruth, write_calibration_set

REPO = Path(__file__).resolve().parents[1]


def _detect_in_process(args):
    name, left, right, board, method = args
    cv2.setNumThreads(1)
    d = detect_pair(name, load_image(left), load_image(right), board, method)
    return d


def _items(found):
    return [PairInput(p.name, (lambda f=p.left: load_image(f)), (lambda f=p.right: load_image(f)),
                      p.left.name, p.right.name) for p in found.pairs]


def _timed(label, fn):
    t = time.perf_counter()
    out = fn()
    dt = time.perf_counter() - t
    print(f"  {label:<48s} {dt:7.2f} s")
    return out, dt


def _accuracy(label, calib, truth: RigTruth, rep) -> None:
    def pct(a, b):
        return 100.0 * (a - b) / b

    parts = []
    for side, M, T in (("L", calib.M1, truth.M1), ("R", calib.M2, truth.M2)):
        for nm, (i, j) in (("fx", (0, 0)), ("fy", (1, 1)), ("cx", (0, 2)), ("cy", (1, 2))):
            parts.append(f"{nm}{side} {pct(M[i, j], T[i, j]):+.3f}%")
    rv, _ = cv2.Rodrigues(calib.R.T @ truth.R)
    print(f"  {label}: " + " ".join(parts))
    print(f"      baseline {pct(calib.baseline_mm, truth.baseline_mm):+.3f}%  rotation error "
          f"{np.degrees(np.linalg.norm(rv)):.4f} deg  RMS L/R/stereo {rep.rms_left:.3f}/"
          f"{rep.rms_right:.3f}/{rep.rms_stereo:.3f} px  epipolar {rep.epipolar_error_px:.3f} px  "
          f"used {rep.pairs_used}/{rep.pairs_found}")


def bench_folder(folder: Path, board: BoardSpec, truth: RigTruth | None, compare: bool) -> None:
    found, _ = _timed("discover pairs", lambda: discover_pairs(folder))
    n = len(found.pairs)
    workers = os.cpu_count() or 1
    dets, t_det = _timed(f"detect {n} pairs, thread pool x{workers} (default)",
                         lambda: detect_pairs(_items(found), board))
    res, t_cal = _timed("calibrate (fixed intrinsics + joint refinement)",
                        lambda: calibrate_stereo(dets, board))
    print(f"  {'TOTAL detection + calibration':<48s} {t_det + t_cal:7.2f} s")
    if truth is not None:
        _accuracy("joint", res.calibration, truth, res.report)
    else:
        r = res.report
        print(f"  used {r.pairs_used}/{r.pairs_found}, rejected "
              f"{[(x.name, x.reason) for x in r.rejected]}; RMS L/R/stereo {r.rms_left:.3f}/"
              f"{r.rms_right:.3f}/{r.rms_stereo:.3f} px, epipolar {r.epipolar_error_px:.3f} px, "
              f"baseline {r.baseline_mm:.2f} mm")
    if not compare:
        return
    fixed, _ = _timed("calibrate (fixed intrinsics only, the report's)",
                      lambda: calibrate_stereo(dets, board, joint_refinement=False))
    if truth is not None:
        _accuracy("fixed", fixed.calibration, truth, fixed.report)
    else:
        print(f"      fixed-intrinsics stereo RMS {fixed.report.rms_stereo:.3f} px")
    _timed(f"detect {n} pairs serially (1 thread, cv2 default threads)",
           lambda: detect_pairs(_items(found), board, workers=1))
    jobs = [(p.name, p.left, p.right, board, "classic") for p in found.pairs]

    def procs():
        # spawn, not fork: forking a process whose OpenCV thread pool is running deadlocks
        with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn")) as pool:
            return list(pool.map(_detect_in_process, jobs))

    _timed(f"detect {n} pairs, process pool x{workers} (incl. start-up)", procs)
    sb, _ = _timed(f"detect {n} pairs with findChessboardCornersSB (threads)",
                   lambda: detect_pairs(_items(found), board, method="sb"))
    if sum(d.found for d in sb) >= 5:
        res_sb = calibrate_stereo(sb, board)
        if truth is not None:
            _accuracy("SB + joint", res_sb.calibration, truth, res_sb.report)
        else:
            print(f"      SB: used {res_sb.report.pairs_used}/{n}, stereo RMS "
                  f"{res_sb.report.rms_stereo:.3f} px")
    else:
        print(f"      SB found the board in both images of only {sum(d.found for d in sb)} pairs")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=50)
    p.add_argument("--seed", type=int, default=5)
    p.add_argument("--real", type=Path, default=REPO.parent / "shared" / "data" / "real-webcam-9x6-30mm")
    p.add_argument("--quick", action="store_true", help="skip the comparisons")
    args = p.parse_args(argv)
    print(f"OpenCV {cv2.__version__}, {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        folder = write_calibration_set(tmp, n_pairs=args.pairs, seed=args.seed)
        print(f"simulated rig, seed {args.seed}: rendered and wrote {args.pairs} pairs in "
              f"{time.perf_counter() - t:.1f} s (not part of the benchmark)")
        truth = RigTruth.from_json(json.loads((folder / "truth.json").read_text()))
        bench_folder(folder, truth.board, truth, not args.quick)
    if args.real and args.real.is_dir():
        print(f"real webcam set {args.real}:")
        bench_folder(args.real, BoardSpec(9, 6, 30.0), None, not args.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())
