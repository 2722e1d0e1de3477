"""Calibration sets on disk: board pairs named as a capture session names them, optional scene
pairs, and truth.json with everything the rig was built with."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Generator, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.files.atomic import AtomicItem, encode_image, json_item, write_many_atomic
from stereo_gui.sources.sim.camera import RigConfig
from stereo_gui.sources.sim.rig import SimRig
from stereo_gui.sources.sim.scene import BoardPose, Scene

SCENE_WALL_DISTANCES_MM = (500.0, 1000.0, 1500.0, 2000.0, 3000.0)
# a board held by hand while the pair is grabbed: its speed along and about each axis (standard
# deviation; a typical hand drifts about 100 mm/s and 10 deg/s, a few pairs much faster)
HAND_SPEED_MM_S = 100.0 / np.sqrt(3.0)
HAND_SPIN_RAD_S = np.radians(10.0) / np.sqrt(3.0)
# scene pairs go into a subfolder so that calibrating OUT_DIR does not take them for board pairs
SCENE_FOLDER = "scenes"

Progress = Callable[[int, int], None]  # progress(done, total)


def calibration_set_names(n_pairs: int, scene: bool) -> list[str]:
    """The file names write_calibration_set writes for these arguments."""
    names = [f"chessboard-{side}{n}.png" for n in range(1, n_pairs + 1) for side in "LR"]
    if scene:
        names += [f"{SCENE_FOLDER}/scene-{side}{k}.png"
                  for k in range(1, len(SCENE_WALL_DISTANCES_MM) + 2) for side in "LR"]
    return names + ["truth.json"]


def _pair_files(out: Path, lname: str, rname: str, left: np.ndarray, right: np.ndarray
                ) -> Iterator[AtomicItem]:
    """A rendered pair as write_many_atomic takes it: (path, encoded bytes, None) twice."""
    yield out / lname, encode_image(out / lname, left), None
    yield out / rname, encode_image(out / rname, right), None


def _board_pairs(rig: SimRig, out: Path, poses: list[BoardPose], rng: np.random.Generator,
                 hand: np.random.Generator, progress: Progress | None, total: int
                 ) -> Generator[AtomicItem, None, list[dict[str, Any]]]:
    """The board pairs' files, rendered one pair at a time; returns their truth.json entries.
    With the rig's time offset the right camera sees the board moved by a hand (`hand`)."""
    offset = float(rig.config.time_offset_s)
    pairs: list[dict[str, Any]] = []
    for n, pose in enumerate(poses, start=1):
        lname, rname = f"chessboard-L{n}.png", f"chessboard-R{n}.png"
        entry: dict[str, Any] = {"n": n, "left": lname, "right": rname, **pose.to_json()}
        pose_right = pose
        if offset:
            # two webcams that are not synchronised: the right one grabs `offset` later,
            # and the board, held by hand, has moved by then
            pose_right = pose.moved(hand.normal(0.0, HAND_SPEED_MM_S, 3),
                                    hand.normal(0.0, HAND_SPIN_RAD_S, 3), offset)
            entry["right_camera_board"] = pose_right.to_json()
        yield from _pair_files(out, lname, rname,
                               *rig.render_board_pair(pose, rng, pose_right=pose_right))
        pairs.append(entry)
        if progress:
            progress(n, total)
    return pairs


def _scene_pairs(rig: SimRig, out: Path, scenes: list[Scene], rng: np.random.Generator,
                 progress: Progress | None, done_before: int, total: int
                 ) -> Generator[AtomicItem, None, list[dict[str, Any]]]:
    """The scene pairs' files under SCENE_FOLDER, after `done_before` board pairs (`progress`
    counts on from them); returns their truth.json entries."""
    entries: list[dict[str, Any]] = []
    for k, sc in enumerate(scenes, start=1):
        lname, rname = f"{SCENE_FOLDER}/scene-L{k}.png", f"{SCENE_FOLDER}/scene-R{k}.png"
        yield from _pair_files(out, lname, rname, *rig.render_scene(sc, rng))
        entry: dict[str, Any] = {"name": sc.name, "left": lname, "right": rname}
        if len(sc.objects) == 1:
            entry["distance_mm"] = float(sc.objects[0].center[2])
        else:
            entry["objects"] = [o.to_json() for o in sc.objects]
        entries.append(entry)
        if progress:
            progress(done_before + k, total)
    return entries


def write_calibration_set(out_dir: str | os.PathLike[str], n_pairs: int = 20, seed: int = 0,
                          scene: bool = False, config: RigConfig | None = None,
                          progress: Progress | None = None, what: str | None = None) -> Path:
    """Write a calibration set named as a capture session names it, plus truth.json; return the
    folder.

    chessboard-L{n}.png / chessboard-R{n}.png for n = 1..n_pairs; with `scene`, also
    scenes/scene-L{k}.png / scenes/scene-R{k}.png for walls at SCENE_WALL_DISTANCES_MM and the
    demo scene, with their true distances in truth.json (paths relative to the folder).
    `progress(done, total)` is called after each pair.

    The set is written as one (files.atomic.write_many_atomic): every image is rendered and
    written under a temporary name first, and only when all are on disk do they replace the
    files of an earlier set, so a disk that fills leaves the earlier set whole, truth.json
    still describing it. `what` names the set in such an error.
    """
    out = Path(out_dir)
    if n_pairs < 0:
        raise InputError(f"number of pairs must not be negative, not {n_pairs}")
    rig = SimRig(config, seed=seed)
    poses = rig.board_poses(n_pairs)
    rng = np.random.default_rng(seed * 104729 + 5)
    offset = float(rig.config.time_offset_s)
    hand = np.random.default_rng(seed * 104729 + 7)  # its own stream: the poses stay the seed's
    scenes = ([Scene.wall(d) for d in SCENE_WALL_DISTANCES_MM] + [Scene.demo()]) if scene else []
    total = len(poses) + len(scenes)
    made_folder = scene and not (out / SCENE_FOLDER).exists()
    if scene:
        (out / SCENE_FOLDER).mkdir(exist_ok=True)

    def files() -> Iterator[AtomicItem]:  # rendered one pair at a time, as write_many_atomic
        pairs = yield from _board_pairs(rig, out, poses, rng, hand, progress, total)
        scene_entries = yield from _scene_pairs(rig, out, scenes, rng, progress,
                                                len(poses), total)
        data = rig.truth.to_json()
        data.update({"seed": int(seed), "generator": "stereo_gui.sources.sim",
                     "noise_sigma": rig.config.noise_sigma, "gain_right": rig.config.gain_right,
                     "time_offset_s": offset, "pairs": pairs})
        if scene:
            data["scenes"] = scene_entries
        yield json_item(out / "truth.json", data)

    try:
        write_many_atomic(files(), what=what)
    except BaseException:
        if made_folder:  # the new set's own folder goes with it
            with contextlib.suppress(OSError):
                (out / SCENE_FOLDER).rmdir()
        raise
    return out
