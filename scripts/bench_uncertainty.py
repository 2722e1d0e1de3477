"""Is the calibration's stated uncertainty honest? Jacobian covariance against a bootstrap.

For several seeds of the simulated rig: calibrate from rendered board pairs, and compare the
true parameters with the estimates in units of the stated 1 sigma (a z-score). An honest sigma
gives |z| < 3 for nearly all parameters and a spread of z near 1. Two sigmas are compared:

- jacobian: sigma^2 (J^T J)^-1 of the joint refinement (core.bundle), what the application uses;
- bootstrap: the spread of the estimates over calibrations from pairs drawn with replacement.

Usage: python scripts/bench_uncertainty.py [--seeds 101 102 ...] [--pairs 20] [--boot 20]
       [--target chessboard|circles|acircles|charuco] [--model pinhole|rational|fisheye]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.calibrate import calibrate_stereo
from stereo_gui.core.detect import detect_pairs
from stereo_gui.sources.sim import RigConfig, SimRig

BOARDS = {"chessboard": BoardSpec(), "circles": BoardSpec(7, 6, 25.0, "circles"),
          "acircles": BoardSpec(4, 11, 20.0, "acircles"),
          "charuco": BoardSpec(8, 6, 30.0, "charuco", 21.0)}


def values(c) -> dict[str, float]:
    out = {}
    for side, M in (("left", c.M1), ("right", c.M2)):
        for k, (i, j) in zip(("fx", "fy", "cx", "cy"), ((0, 0), (1, 1), (0, 2), (1, 2))):
            out[f"{side}.{k}"] = float(M[i, j])
    out["baseline"] = c.baseline_mm
    out["rotation"] = c.relative_rotation_deg
    return out


def sigmas(c) -> dict[str, float]:
    u = c.uncertainty
    out = {n: u.sigma(n) for n in values(c) if "." in n}
    out["baseline"] = u.baseline_sigma_mm(c.T)
    out["rotation"] = u.rotation_sigma_deg(c.R)
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[101, 102, 103, 104, 105, 106])
    ap.add_argument("--pairs", type=int, default=20)
    ap.add_argument("--boot", type=int, default=20)
    ap.add_argument("--target", default="chessboard", choices=sorted(BOARDS))
    ap.add_argument("--model", default="pinhole", choices=("pinhole", "rational", "fisheye"))
    args = ap.parse_args()
    board = BOARDS[args.target]
    z_jac, z_boot, ratio = [], [], []
    t_jac = t_boot = 0.0
    for seed in args.seeds:
        cfg = RigConfig.fisheye(board=board) if args.model == "fisheye" else RigConfig(board=board)
        rig = SimRig(cfg, seed=seed)
        imgs = rig.calibration_set(args.pairs)
        dets = detect_pairs([(f"p{i}", l, r) for i, (l, r) in enumerate(imgs)], board)
        t0 = time.perf_counter()
        c = calibrate_stereo(dets, board, model=args.model).calibration
        t_jac += time.perf_counter() - t0
        truth = values(rig.true_calibration())
        est, sig = values(c), sigmas(c)
        rng = np.random.default_rng(seed)
        boots = []
        t0 = time.perf_counter()
        for _ in range(args.boot):
            pick = [dets[i] for i in rng.integers(0, len(dets), len(dets))]
            try:
                boots.append(values(calibrate_stereo(pick, board, model=args.model,
                                                     reject_outliers=False).calibration))
            except Exception as exc:  # noqa: BLE001 - a degenerate resample is skipped
                print("  bootstrap sample failed:", exc)
        t_boot += time.perf_counter() - t0
        bsig = {k: float(np.std([b[k] for b in boots], ddof=1)) for k in est}
        for k in est:
            z_jac.append((est[k] - truth[k]) / sig[k])
            z_boot.append((est[k] - truth[k]) / bsig[k])
            ratio.append(sig[k] / bsig[k])
        print(f"seed {seed}: " + "  ".join(f"{k} z {(est[k] - truth[k]) / sig[k]:+.1f}"
                                           for k in est))
    zj, zb = np.abs(np.array(z_jac)), np.abs(np.array(z_boot))
    print(f"\n{args.target}, {args.model}, {args.pairs} pairs, {len(args.seeds)} seeds, "
          f"{len(zj)} parameters")
    print(f"jacobian : within 3 sigma {100 * np.mean(zj < 3):.0f} %, within 1 sigma "
          f"{100 * np.mean(zj < 1):.0f} %, RMS z {np.sqrt(np.mean(zj ** 2)):.2f}, "
          f"{t_jac / len(args.seeds):.2f} s per calibration")
    print(f"bootstrap: within 3 sigma {100 * np.mean(zb < 3):.0f} %, within 1 sigma "
          f"{100 * np.mean(zb < 1):.0f} %, RMS z {np.sqrt(np.mean(zb ** 2)):.2f}, "
          f"{t_boot / len(args.seeds):.1f} s per calibration ({args.boot} resamples)")
    print(f"sigma jacobian / sigma bootstrap: median {np.median(ratio):.2f}")


if __name__ == "__main__":
    main()
