"""The simulated stereo rig: board poses seen by both cameras, rendering of board and scene
pairs (rays through OpenCV's distortion model, textures, supersampling, sensor noise), and the
ground truth a perfect calibration and a perfect measurement would find."""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import ArrayLike

from stereo_gui.core import detect
from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import InputError
from stereo_gui.core.lens import project_points, stereo_rectify
from stereo_gui.core.shading import LensShading, PairShading
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.sources.sim.camera import RigConfig, RigTruth
from stereo_gui.sources.sim.conditions import Condition
from stereo_gui.sources.sim.controls import CameraLook
from stereo_gui.sources.sim.rays import ray_map
from stereo_gui.sources.sim.scene import BoardPose, Scene, SceneObject
from stereo_gui.sources.sim.textures import _board_texture, _texture

# the rig shows the target no smaller than this (neighbouring points this far apart), as a
# careful technician would: smaller, its points cannot be placed to a tenth of a pixel
MIN_POINT_SPACING_PX = 9.0
_BOARD_BACKGROUND = 118.0  # plain grey behind the board when no scene is shown
_NOISE_PAD = 64  # the noise bank is this much larger than an image (random crops)
# the board's outline in the image is a polygon of this many sides an edge, and the rays within
# half this many supersamples of it are worked out one by one: the polygon lies within half a
# supersample of the curved outline, fillPoly's edge within 1.8 of the polygon (measured on
# polygons reaching far beyond the canvas; 1.1 inside it)
_OUTLINE_STEPS = 32
_EDGE_PX = 7
_OPEN = 128  # a ray that _board_rays leaves to be worked out on its own
_FLT_EPS = float(np.finfo(np.float32).eps)  # perspectiveTransform's least denominator


class BoardOutOfView(InputError):
    """No pose of the rig's board is seen by both cameras as a calibration view needs."""


@dataclass(frozen=True)
class SimFrameTruth:
    """Ground truth attached to a simulated frame (StereoFrame.truth)."""

    pose: BoardPose | None
    scene: Scene | None
    truth: RigTruth
    # the board's pose when the right camera took its picture (the cameras' time offset), and
    # each camera's focal length relative to the truth's (its focus moved); the truth holds
    # only where these are the board's pose and 1
    pose_right: BoardPose | None = None
    focal_scale: tuple[float, float] = (1.0, 1.0)

    def point_rectified(self, calib: StereoCalibration, x: float, y: float
                        ) -> np.ndarray | None:
        """True (X, Y, Z) mm in the left rectified frame of `calib` of what the left camera
        sees at rectified pixel (x, y): the nearest of the board (when shown) and the scene's
        objects, or None where the ray hits nothing (the plain background)."""
        ray_rect = np.linalg.inv(np.asarray(calib.P1, np.float64)[:, :3]) @ np.array([x, y, 1.0])
        R1 = np.asarray(calib.R1, np.float64)
        ray = R1.T @ ray_rect
        ray /= np.linalg.norm(ray)
        hits = []
        if self.scene is not None:
            t = self.scene.depth_along_ray(np.zeros(3), ray)
            if t is not None:
                hits.append(t)
        if self.pose is not None and self.truth.board is not None:
            t = _board_hit(self.pose, self.truth.board, ray)
            if t is not None:
                hits.append(t)
        return R1 @ (min(hits) * ray) if hits else None


def _board_hit(pose: BoardPose, board: BoardSpec, ray: np.ndarray) -> float | None:
    """Ray parameter (mm along the unit `ray` from the left camera) of its hit with the
    printed board, or None."""
    R, t = np.asarray(pose.R, np.float64), np.asarray(pose.t, np.float64).reshape(3)
    n = R[:, 2]
    denom = float(n @ ray)
    if abs(denom) < 1e-12:
        return None
    s = float(n @ t) / denom
    if s <= 0:
        return None
    a, b = R[:, :2].T @ (s * ray - t)
    a0, b0, a1, b1 = board.outline_mm()
    return s if a0 <= a <= a1 and b0 <= b <= b1 else None


def _square_ring(steps: int) -> np.ndarray:
    """The unit square's outline from (0, 0) through (1, 0), (1, 1) and (0, 1), (8 steps, 2):
    the vertices of a polygon of `steps` sides a side (even rows) and the midpoints between
    them (odd rows)."""
    k = np.arange(2 * steps) / (2 * steps)
    zero, one = np.zeros_like(k), np.ones_like(k)
    return np.concatenate([np.stack([k, zero], 1), np.stack([one, k], 1),
                           np.stack([1 - k, one], 1), np.stack([zero, 1 - k], 1)])


_SQUARE_RING = _square_ring(_OUTLINE_STEPS)


def _sample(tex: np.ndarray, tmap: np.ndarray) -> np.ndarray:
    """The texture `tex` at texel coordinates `tmap` (bilinear, 0 outside it)."""
    sampled: np.ndarray = cv2.remap(tex, tmap, None, cv2.INTER_LINEAR,
                                    borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0))
    return sampled


def _depth(xy: np.ndarray, Hz: np.ndarray) -> np.ndarray:
    """The depth (mm) at which rays (x, y, 1) meet a plane (Hz of SimRig._plane_maps); 0 for
    rays along it."""
    z: np.ndarray = cv2.perspectiveTransform(xy, Hz)[..., 0]
    return z


def _seen(alpha: np.ndarray, z: np.ndarray, zb: np.ndarray | None) -> np.ndarray:
    """Which rays show a textured plane (uint8 mask): those in its texture (remapped `alpha`
    over 127), in front of the camera (depth `z`) and, given a depth buffer `zb`, nearer."""
    # (OpenCV's stubs take no number for src2; cv2.compare does)
    mask: np.ndarray = cv2.compare(alpha, 127, cv2.CMP_GT)  # type: ignore[call-overload]
    cv2.bitwise_and(mask, cv2.compare(z, 0.0, cv2.CMP_GT),  # type: ignore[call-overload]
                    dst=mask)
    if zb is not None:
        cv2.bitwise_and(mask, cv2.compare(z, zb, cv2.CMP_LT), dst=mask)
    return mask


@dataclass(frozen=True, eq=False)
class _Plane:
    """A rectangle in one camera's frame, ready for rendering: origin + a*u + b*v, a in
    [0, width], b in [0, height] (mm)."""

    origin: np.ndarray
    u: np.ndarray
    v: np.ndarray
    width: float
    height: float


def _random_tilt(rng: np.random.Generator) -> np.ndarray | None:
    """A random board orientation (3x3): tilts up to 40 deg about x and y, spin up to 20 deg;
    None (having drawn only the tilts) when the tilts together exceed 45 deg."""
    tilt_x = math.radians(rng.uniform(-40, 40))
    tilt_y = math.radians(rng.uniform(-40, 40))
    if math.hypot(tilt_x, tilt_y) > math.radians(45):
        return None
    spin = math.radians(rng.uniform(-20, 20))
    R: np.ndarray = (cv2.Rodrigues(np.array([0.0, tilt_y, 0.0]))[0]
                     @ cv2.Rodrigues(np.array([tilt_x, 0.0, 0.0]))[0]
                     @ cv2.Rodrigues(np.array([0.0, 0.0, spin]))[0])
    return R


def _placement_fraction(rng: np.random.Generator, where: tuple[float, float] | None
                        ) -> np.ndarray:
    """Where in the room it leaves a board goes (x, y fractions): near `where`, or anywhere with
    a bias towards the edges and corners."""
    if where is None:
        return rng.beta(0.5, 0.5, 2)
    return np.clip(np.asarray(where, np.float64) + rng.normal(0.0, 0.08, 2), 0, 1)


class SimRig:
    """A simulated stereo rig with known truth that renders board and scene pairs."""

    def __init__(self, config: RigConfig | None = None, seed: int = 0):
        self.config = config or RigConfig()
        self.seed = int(seed)
        c = self.config
        R, _ = cv2.Rodrigues(np.asarray(c.rvec_right_left, np.float64).reshape(3, 1))
        tdir = np.asarray(c.t_direction, np.float64).reshape(3)
        T = (tdir / np.linalg.norm(tdir) * c.baseline_mm).reshape(3, 1)
        self.truth = RigTruth((c.image_size[0], c.image_size[1]), c.left.M.copy(), c.left.D.copy(),
                              c.right.M.copy(), c.right.D.copy(), R, T, c.board, c.model)
        # rays beyond this tangent of the off-axis angle are not trusted: the pinhole models'
        # polynomials fold back beyond about 50 degrees; the fisheye model holds further out
        self._max_tan = 0.9 if c.model != "fisheye" else 2.5
        self._rays = (ray_map(c.left, c.image_size, c.supersample),
                      ray_map(c.right, c.image_size, c.supersample))
        # (camera, id(scene)) -> (scene, supersampled image, depth buffer, image)
        self._scene_cache: dict[tuple[int, int], tuple[Scene | None, np.ndarray, np.ndarray,
                                                       np.ndarray]] = {}
        self._noise: dict[int | str, np.ndarray] = {}  # noise banks per camera, the vignette
        self._lock = threading.Lock()
        self._untouched: RigTruth | None = None  # the truth before turn_right_camera

    def set_board(self, board: BoardSpec) -> None:
        """Show another target from the next frame on (the Capture tab's choice, for demos);
        the truth's board follows."""
        with self._lock:
            self.config = replace(self.config, board=board)
            self.truth = replace(self.truth, board=board)

    def set_sensor(self, condition: Condition) -> None:
        """Render from the next frame on with the sensor and webcam effects of `condition`
        (sim/conditions.py: noise, the right camera's gain and black level, vignetting, JPEG)."""
        with self._lock:
            self.config = condition.rig_config(self.config)
            self._noise.clear()  # the noise banks and the vignette follow the new settings

    TURN_AXES = {"tilt": 0, "pan": 1, "roll": 2}  # about the right camera's x, y, z axes

    def turn_right_camera(self, angle_deg: float, axis: str = "tilt") -> None:
        """Turn the right camera about its own centre by `angle_deg` (tilt: about its x axis,
        pan: y, roll: z), as a webcam head that moved after calibration; the truth follows
        (R' = dR R, T' = dR T: the camera's centre stays). Cumulative; reset_turn() undoes."""
        if axis not in self.TURN_AXES:
            raise ValueError(f"axis must be one of {', '.join(self.TURN_AXES)}, not {axis!r}")
        v = np.zeros(3)
        v[self.TURN_AXES[axis]] = math.radians(float(angle_deg))
        dR = cv2.Rodrigues(v.reshape(3, 1))[0]
        with self._lock:
            if self._untouched is None:
                self._untouched = self.truth
            t = self.truth
            self.truth = replace(t, R=dR @ t.R, T=dR @ t.T)
            self._scene_cache.clear()  # the right camera's view of the scene changed

    def reset_turn(self) -> None:
        """Put the right camera back where the rig was built."""
        with self._lock:
            if self._untouched is not None:
                self.truth = self._untouched
                self._untouched = None
                self._scene_cache.clear()

    @property
    def turned_deg(self) -> float:
        """How far the right camera is turned from where the rig was built, degrees."""
        if self._untouched is None:
            return 0.0
        d = self.truth.R @ self._untouched.R.T
        return float(np.degrees(np.linalg.norm(cv2.Rodrigues(d)[0])))

    # ---- geometry -------------------------------------------------------------------------
    def _to_camera(self, cam: int, p: np.ndarray) -> np.ndarray:
        """Points (..., 3) in the left frame -> camera `cam` (0 left, 1 right) frame."""
        if cam == 0:
            return p
        moved: np.ndarray = p @ self.truth.R.T + self.truth.T.reshape(3)
        return moved

    def _dir_to_camera(self, cam: int, d: np.ndarray) -> np.ndarray:
        return d if cam == 0 else d @ self.truth.R.T

    def project(self, points_left_mm: np.ndarray, cam: int) -> np.ndarray:
        """Project (N, 3) left-frame points (mm) into camera `cam`'s image, (N, 2) px."""
        t = self.truth
        M, D = (t.M1, t.D1) if cam == 0 else (t.M2, t.D2)
        rvec = np.zeros(3) if cam == 0 else cv2.Rodrigues(t.R)[0]
        tvec = np.zeros(3) if cam == 0 else t.T.reshape(3)
        return project_points(t.model, points_left_mm, rvec, tvec, M, D)

    def board_outline_mm(self) -> tuple[float, float, float, float]:
        """The printed target (pattern plus white border) on its plane: (a0, b0, a1, b1) mm."""
        return self.config.board.outline_mm()

    def _board_visible(self, pose: BoardPose, margin_px: float = 8.0) -> bool:
        """Whether both cameras see the board at `pose` well enough for a calibration view: all
        of it inside both images by `margin_px` (targets that must be seen whole), or, for a
        ChArUco board, enough of its corners in both (the rest may lie outside the images)."""
        least = MIN_POINT_SPACING_PX * (1.5 if self.config.board.target in ("circles", "acircles")
                                        else 1.0)  # circles shrink to a few pixels sooner
        if self._point_spacing_px(pose) < least:
            return False  # too small to place its points to a fraction of a pixel
        if self.config.board.partial:
            return self._enough_corners_visible(pose, margin_px)
        # densely sample the outline: the distorted image of a straight edge is curved
        edge = self._outline_samples(17)
        pts = np.concatenate([edge, np.zeros((len(edge), 1))], 1) @ pose.R.T + pose.t
        w, h = self.config.image_size
        for cam in (0, 1):
            pc = self._to_camera(cam, pts)
            if np.any(pc[:, 2] < 100.0):
                return False
            # beyond about 50 degrees off-axis the distortion polynomial is not meaningful
            if np.any(np.hypot(pc[:, 0], pc[:, 1]) / pc[:, 2] > self._max_tan):
                return False
            uv = self.project(pts, cam)
            if (uv[:, 0].min() < margin_px or uv[:, 1].min() < margin_px
                    or uv[:, 0].max() > w - 1 - margin_px or uv[:, 1].max() > h - 1 - margin_px):
                return False
        return True

    def _point_spacing_px(self, pose: BoardPose) -> float:
        """The smallest distance between neighbouring points of the target that a camera sees
        (both inside its image), in either image, px."""
        b = self.config.board
        rows, cols = b.grid_shape
        pts = pose.corners_left_mm(b)
        best = np.inf
        for cam in (0, 1):
            if np.any(self._to_camera(cam, pts)[:, 2] < 50.0):
                return 0.0
            seen: np.ndarray = np.zeros(rows * cols, bool)
            seen[self.visible_point_ids(pose, cam)] = True
            seen = seen.reshape(rows, cols)
            uv = self.project(pts, cam).reshape(rows, cols, 2)
            for axis in (0, 1):
                both = np.logical_and(*(np.take(seen, range(0, seen.shape[axis] - 1), axis),
                                        np.take(seen, range(1, seen.shape[axis]), axis)))
                if both.any():
                    d = np.linalg.norm(np.diff(uv, axis=axis), axis=2)[both]
                    best = min(best, float(d.min()))
        return best

    def visible_point_ids(self, pose: BoardPose, cam: int, margin_px: float = 0.0) -> np.ndarray:
        """Ids of the target's points that camera `cam` sees inside its image (by `margin_px`)."""
        b = self.config.board
        pts = pose.corners_left_mm(b)
        pc = self._to_camera(cam, pts)
        ok = (pc[:, 2] > 100.0) & (np.hypot(pc[:, 0], pc[:, 1]) / np.maximum(pc[:, 2], 1e-9)
                                   < self._max_tan)
        uv = self.project(pts, cam)
        w, h = self.config.image_size
        ok &= ((uv[:, 0] >= margin_px) & (uv[:, 1] >= margin_px)
               & (uv[:, 0] <= w - 1 - margin_px) & (uv[:, 1] <= h - 1 - margin_px))
        return np.flatnonzero(ok)

    def _enough_corners_visible(self, pose: BoardPose, margin_px: float) -> bool:
        a0, b0, a1, b1 = self.board_outline_mm()
        outline = np.array([[a0, b0, 0], [a1, b0, 0], [a1, b1, 0], [a0, b1, 0]], np.float64)
        pts = outline @ pose.R.T + pose.t
        for cam in (0, 1):
            if np.any(self._to_camera(cam, pts)[:, 2] < 100.0):
                return False
        b = self.config.board
        # the gap between corners and markers must stay large enough to place the corners
        gap = (b.square_mm - b.marker_mm) / (2.0 * b.square_mm)
        if self._point_spacing_px(pose) * gap < 1.3 * detect.CHARUCO_MIN_GAP_PX:
            return False
        # a corner is found only next to whole markers: keep a square's width inside the images
        m = margin_px + 1.1 * self._square_px(pose)
        common = np.intersect1d(self.visible_point_ids(pose, 0, m),
                                self.visible_point_ids(pose, 1, m))
        r, c = b.grid_shape
        rows, cols = np.unique(common // c), np.unique(common % c)
        return common.size >= max(b.min_points + 4, 0.3 * b.point_count) and rows.size >= 2 \
            and cols.size >= 2

    def _square_px(self, pose: BoardPose) -> float:
        """About how many pixels a square spans at `pose` (for margins)."""
        b = self.config.board
        z = float((pose.R @ b.object_points_mm().astype(np.float64).mean(0) + pose.t)[2])
        return float(self.truth.M1[0, 0]) * b.square_mm / max(z, 100.0)

    # the places the poses of a calibration set visit in turn: corners first, then edges and
    # the centre, as fractions of the room the board leaves in the images (0 left/top, 1
    # right/bottom); the image corners are where the distortion shows most
    PLACES = ((0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0), (0.5, 0.5), (0.5, 0.0),
              (0.0, 0.5), (1.0, 0.5), (0.5, 1.0))

    def _outline_samples(self, n: int) -> np.ndarray:
        """n points along each edge of the board's outline, (4n, 2) mm in the board's plane."""
        a0, b0, a1, b1 = self.board_outline_mm()
        k = np.linspace(0.0, 1.0, n)
        return np.concatenate([
            np.stack([a0 + (a1 - a0) * k, np.full_like(k, b0)], 1),
            np.stack([a0 + (a1 - a0) * k, np.full_like(k, b1)], 1),
            np.stack([np.full_like(k, a0), b0 + (b1 - b0) * k], 1),
            np.stack([np.full_like(k, a1), b0 + (b1 - b0) * k], 1)])

    def _hidden_by(self, pose: BoardPose, scene: Scene) -> bool:
        """Whether an object of `scene` stands between a camera and part of the board (its
        outline or its points): a board held behind an object is not seen whole."""
        plane = self._outline_samples(9)
        pts = np.concatenate([np.concatenate([plane, np.zeros((len(plane), 1))], 1)
                              @ pose.R.T + pose.t, pose.corners_left_mm(self.config.board)])
        t = self.truth
        for origin in (np.zeros(3), (-t.R.T @ t.T).reshape(3)):
            d = pts - origin
            dist = np.linalg.norm(d, axis=1)
            d = d / dist[:, None]
            for obj in scene.objects:
                n = obj.normal
                denom = d @ n
                with np.errstate(divide="ignore", invalid="ignore"):
                    s_hit = ((obj.center - origin) @ n) / denom
                q = origin + s_hit[:, None] * d - obj.center
                inside = ((np.abs(q @ obj.u) <= obj.width_mm / 2)
                          & (np.abs(q @ obj.v) <= obj.height_mm / 2))
                if np.any(inside & (np.abs(denom) > 1e-12) & (s_hit > 0) & (s_hit < dist - 1.0)):
                    return True
        return False

    def random_board_pose(self, rng: np.random.Generator, max_tries: int = 2000,
                          where: tuple[float, float] | None = None,
                          scene: Scene | None = None) -> BoardPose:
        """One random board pose seen by both cameras (0.4-1.2 m, up to 1.6 m for the left and
        right edges; tilts up to 40 deg).

        Depth and tilt are drawn first; the position is then drawn over the room the board
        leaves in both images: near `where` (fractions of that room, 0 = left/top edge, 1 =
        right/bottom edge), or anywhere with a bias towards the edges and corners (which
        a calibration needs to see the distortion). A board that must be seen whole (chessboard,
        circle grids) stays inside both images by a few pixels; a ChArUco board may reach out
        of them by a good part of its size, as long as both cameras see enough of its corners.
        With a `scene`, the board is held in front of its objects, never behind one.
        """
        b = self.config.board
        margin = 4.0
        centre_board = b.object_points_mm().astype(np.float64).mean(0)
        centre_board[2] = 0.0
        edges = self._outline_samples(9)  # the outline's image is curved: sample its edges
        outline = np.concatenate([edges, np.zeros((len(edges), 1))], 1)
        f = float(self.truth.M1[0, 0])
        z_lo, z_hi = self._pose_depth_range(where, f)
        zoom = f / 750.0
        # the nearest and farthest any whole board is placed (see _pose_depth_range)
        out_of_view = self._out_of_view(400.0 * zoom, 1600.0 * zoom, f)
        if out_of_view is not None:
            raise out_of_view
        for _ in range(max_tries):
            z = rng.uniform(z_lo, z_hi)
            R = _random_tilt(rng)
            if R is None:
                continue
            t0 = np.array([0.0, 0.0, z]) - R @ centre_board
            pts = outline @ R.T + t0
            if np.any(pts[:, 2] < 150.0 * zoom):
                continue
            frac = _placement_fraction(rng, where)
            shift = self._shift_into_room(pts, frac, z, f, margin)
            if shift is None:
                continue
            pose = BoardPose(R, t0 + np.array([shift[0] * z / f, shift[1] * z / f, 0.0]))
            if self._board_visible(pose, margin_px=margin - 2.0) and (
                    scene is None or not self._hidden_by(pose, scene)):
                return pose
        raise BoardOutOfView(f"could not find a pose of the {b.label()} board that both "
                             f"simulated cameras see whole between {z_lo:.0f} and {z_hi:.0f} mm "
                             "(a board this large fits only in a few places: give a smaller "
                             "square size)")

    def _pose_depth_range(self, where: tuple[float, float] | None, f: float
                          ) -> tuple[float, float]:
        """(nearest, farthest) mm a random board pose is drawn at, for focal length `f` px."""
        # the outer edges of the left image and of the right one are seen by both cameras only
        # when the board is far (the other camera sees it shifted by the disparity): poses of a
        # whole board meant for the left or right edge reach farther; a ChArUco board reaches
        # them partly outside the other image, and must stay near enough to read its corners
        if self.config.board.partial:
            z_lo, z_hi = 300.0, 1000.0
        elif where is not None and where[0] in (0.0, 1.0):
            z_lo, z_hi = 700.0, 1600.0
        else:
            z_lo, z_hi = 400.0, 1200.0
        # distances are for the default webcams (750 px focal length): a wide-angle camera
        # sees the board as large from nearer
        zoom = f / 750.0
        return z_lo * zoom, z_hi * zoom

    def _shift_into_room(self, pts: np.ndarray, frac: np.ndarray, z: float, f: float,
                         margin: float) -> np.ndarray | None:
        """The image shift (px, x and y) that places the board outline `pts` (mm, at depth `z`)
        at `frac` of the room it leaves in both images, `margin` px from their edges; None when
        it has no room. A few corrections, because the distortion does not move it in the
        image as far as it moves in space."""
        b = self.config.board
        w, h = self.config.image_size
        shift = np.zeros(2)
        for _ in range(6):
            moved = pts + np.array([shift[0] * z / f, shift[1] * z / f, 0.0])
            lo_room, hi_room = np.full(2, np.inf), np.full(2, np.inf)
            for cam in (0, 1):
                uv = self.project(moved, cam)
                out = 0.5 * np.ptp(uv, axis=0) if b.partial else np.zeros(2)
                lo_room = np.minimum(lo_room, uv.min(0) - margin + out)
                hi_room = np.minimum(hi_room, np.array([w - 1.0, h - 1.0]) - margin
                                     - uv.max(0) + out)
            room = lo_room + hi_room
            if np.any(room <= 0):
                return None
            step = frac * room - lo_room
            shift += step
            if np.all(np.abs(step) < 0.5):
                break
        return shift

    def _out_of_view(self, z_lo: float, z_hi: float, f: float) -> BoardOutOfView | None:
        """Why no pose between z_lo and z_hi mm can show the board to both cameras as a
        calibration view needs (too large to be seen whole facing them at the farthest, its
        points too close together at the nearest), with the square sizes that can be; None
        when one may."""
        b = self.config.board
        w, h = self.config.image_size
        a0, b0, a1, b1 = self.board_outline_mm()
        scale = min(w * z_hi / (f * (a1 - a0)), h * z_hi / (f * (b1 - b0)))
        least = MIN_POINT_SPACING_PX * (1.5 if b.target in ("circles", "acircles") else 1.0)
        smallest = least * z_lo / f  # square size whose points are `least` px apart nearest
        largest = b.square_mm * scale
        if b.partial or smallest <= b.square_mm <= largest:
            return None
        why = (f"it is {a1 - a0:.0f} x {b1 - b0:.0f} mm with its border, more than they see at "
               f"{z_hi:.0f} mm" if b.square_mm > largest else
               f"its points would be less than {least:g} px apart even at {z_lo:.0f} mm")
        return BoardOutOfView(f"the simulated cameras cannot see the {b.label()} board whole: "
                              f"{why}; give a square size from about {smallest:.1f} to "
                              f"{largest:.0f} mm")

    def board_poses(self, n: int, seed: int | None = None) -> list[BoardPose]:
        """`n` varied board poses (0.4-1.2 m, tilts up to 40 deg) that visit the image corners,
        edges and centre in turn (PLACES), each seen by both cameras (see random_board_pose)."""
        rng = np.random.default_rng(self.seed * 7919 + 17 if seed is None else seed)
        return [self.place_pose(rng, i) for i in range(int(n))]

    def place_pose(self, rng: np.random.Generator, i: int, scene: Scene | None = None
                   ) -> BoardPose:
        """A random board pose at the i-th of PLACES (in turn, from the first again after the
        last), seen by both cameras (in front of `scene`'s objects); a place out of reach is
        pulled a little nearer the centre."""
        where = np.array(self.PLACES[i % len(self.PLACES)])
        for pull in (0.0, 0.25):
            try:
                return self.random_board_pose(rng, max_tries=400, scene=scene,
                                              where=tuple(where + pull * (0.5 - where)))
            except BoardOutOfView:
                pass
        return self.random_board_pose(rng, max_tries=2000, scene=scene,
                                      where=tuple(where + 0.5 * (0.5 - where)))

    # ---- rendering ------------------------------------------------------------------------
    def _plane_in_camera(self, cam: int, origin: ArrayLike, u: ArrayLike, v: ArrayLike,
                         width: float, height: float) -> _Plane:
        return _Plane(self._to_camera(cam, np.asarray(origin, np.float64)),
                      self._dir_to_camera(cam, np.asarray(u, np.float64)),
                      self._dir_to_camera(cam, np.asarray(v, np.float64)), width, height)

    def _bbox(self, cam: int, plane_left: _Plane) -> tuple[int, int, int, int] | None:
        """Supersample-grid box (x0, y0, x1, y1) that contains the plane's image, or None."""
        s = self.config.supersample
        w, h = self.config.image_size
        k = np.linspace(0.0, 1.0, 33)
        ab = np.concatenate([
            np.stack([k * plane_left.width, np.zeros_like(k)], 1),
            np.stack([k * plane_left.width, np.full_like(k, plane_left.height)], 1),
            np.stack([np.zeros_like(k), k * plane_left.height], 1),
            np.stack([np.full_like(k, plane_left.width), k * plane_left.height], 1)])
        pts = plane_left.origin + ab[:, :1] * plane_left.u + ab[:, 1:] * plane_left.v
        pc = self._to_camera(cam, pts)
        if np.all(pc[:, 2] <= 0):
            return None
        rad = np.hypot(pc[:, 0], pc[:, 1]) / np.maximum(pc[:, 2], 1e-9)
        if np.any(pc[:, 2] <= 1.0) or np.any(rad > self._max_tan):
            return (0, 0, w * s, h * s)  # partly behind or far off-axis: test every ray
        uv = self.project(pts, cam)
        x0 = int(math.floor((uv[:, 0].min() - 3) * s))
        y0 = int(math.floor((uv[:, 1].min() - 3) * s))
        x1 = int(math.ceil((uv[:, 0].max() + 4) * s))
        y1 = int(math.ceil((uv[:, 1].max() + 4) * s))
        x0, y0 = max(0, x0), max(0, y0)
        x1, y1 = min(w * s, x1), min(h * s, y1)
        if x1 <= x0 or y1 <= y0:
            return None
        return (x0, y0, x1, y1)

    def _plane_maps(self, cam: int, plane_left: _Plane, texel: float
                    ) -> tuple[np.ndarray, np.ndarray] | None:
        """Homographies of camera `cam`'s rays (x, y, 1) to where they meet the plane: H to the
        texel coordinates of its texture (texel centres at whole numbers), Hz to the depth (as
        (depth, 0)); None when the plane passes through the camera centre (seen edge-on)."""
        pl = self._plane_in_camera(cam, plane_left.origin, plane_left.u, plane_left.v,
                                   plane_left.width, plane_left.height)
        n = np.cross(pl.u, pl.v)
        npo = float(n @ pl.origin)
        if abs(npo) < 1e-9:
            return None
        # a ray t*(x, y, 1) meets the plane at depth t = n.o / n.r, where (a, b) =
        # (u.(t r - o), v.(t r - o)): a homography of (x, y, 1); fold in mm -> texel centres
        Ha = npo * pl.u - float(pl.u @ pl.origin) * n
        Hb = npo * pl.v - float(pl.v @ pl.origin) * n
        H = np.stack([Ha / texel - 0.5 * n, Hb / texel - 0.5 * n, n])
        Hz = np.array([[0.0, 0.0, npo], [0.0, 0.0, 0.0], n])  # (x, y, 1) -> (depth, 0)
        return H, Hz

    def _draw_plane(self, cam: int, plane_left: _Plane, tex: np.ndarray, texel: float,
                    img: np.ndarray, zbuf: np.ndarray) -> None:
        """Draw a textured rectangle (a scene's object) into camera `cam`'s supersampled `img`,
        with a depth test against `zbuf`, which takes its depth where it is drawn.

        The texture (BGRA) spans the rectangle (texel centres at (i + 0.5) * texel mm); its
        alpha is 255 (remap's zero border marks rays that miss the rectangle).
        """
        box = self._bbox(cam, plane_left)
        maps = self._plane_maps(cam, plane_left, texel)
        if box is None or maps is None:
            return
        H, Hz = maps
        x0, y0, x1, y1 = box
        xy = self._rays[cam].xy[y0:y1, x0:x1]  # (a view: OpenCV takes its row stride)
        sampled = _sample(tex, cv2.perspectiveTransform(xy, H))
        z = _depth(xy, Hz)
        zb = zbuf[y0:y1, x0:x1]
        mask = _seen(sampled[..., 3], z, zb)
        cv2.copyTo(z, mask, zb)
        # (cvtColor drops the alpha channel much faster than numpy's copy of a channel slice)
        cv2.copyTo(cv2.cvtColor(sampled, cv2.COLOR_BGRA2BGR), mask, img[y0:y1, x0:x1])

    def _draw_board(self, cam: int, plane_left: _Plane, box: tuple[int, int, int, int],
                    img: np.ndarray, origin: tuple[int, int], zbuf: np.ndarray | None) -> None:
        """Draw the board (its plane `plane_left`, its box `box` from _bbox) into `img`, a crop
        of camera `cam`'s supersampled image from supersample (x, y) = `origin` that holds the
        box, behind what is nearer in the scene's depth buffer `zbuf` (None: no scene).

        The very pixels _draw_plane would draw, for less: the grey texture is remapped on one
        channel, and which rays show the board is worked out ray by ray (as _draw_plane does)
        only where the board's outline in the image leaves it open (_board_rays).
        """
        grey, alpha, texel = _board_texture(self.config.board)
        maps = self._plane_maps(cam, plane_left, texel)
        if maps is None:
            return
        H, Hz = maps
        x0, y0, x1, y1 = box
        rays = self._rays[cam].xy
        xy = rays[y0:y1, x0:x1]  # (a view: OpenCV takes its row stride)
        tmap = cv2.perspectiveTransform(xy, H)
        zb = None if zbuf is None else zbuf[y0:y1, x0:x1]
        mask = self._board_rays(cam, plane_left, texel, grey.shape, box, Hz, zb)
        if mask is None:
            mask = _seen(_sample(alpha, tmap), _depth(xy, Hz), zb)
        else:
            found = cv2.findNonZero(cv2.compare(mask, _OPEN,  # type: ignore[call-overload]
                                                cv2.CMP_EQ))  # (x, y) in the box
            if found is not None:
                # the open rays in rows of 1024 (remap takes fewer than 32767 columns), the first
                # ones again to fill the last row: remap and perspectiveTransform take each ray
                # on its own; `full` indexes the same rays on the whole supersample grid
                at = np.asarray(found, np.int32).reshape(-1, 2)
                x, y = np.resize(at, (-(-len(at) // 1024) * 1024, 2)).T
                i = y * (x1 - x0) + x
                full = (y + y0) * rays.shape[1] + x + x0
                rows = (-1, 1024)
                np.put(mask, i, _seen(
                    _sample(alpha, np.take(tmap.reshape(-1, 2), i, axis=0).reshape(*rows, 2)),
                    _depth(np.take(rays.reshape(-1, 2), full, axis=0).reshape(*rows, 2), Hz),
                    None if zbuf is None else np.take(zbuf, full).reshape(rows)))
        ox, oy = origin
        cv2.copyTo(cv2.cvtColor(_sample(grey, tmap), cv2.COLOR_GRAY2BGR), mask,
                   img[y0 - oy:y1 - oy, x0 - ox:x1 - ox])

    def _board_rays(self, cam: int, plane_left: _Plane, texel: float, tex_shape: tuple[int, ...],
                    box: tuple[int, int, int, int], Hz: np.ndarray, zb: np.ndarray | None
                    ) -> np.ndarray | None:
        """Which rays of camera `cam` in `box` show the board as far as its outline in the image
        tells (uint8: 255 they do, 0 they do not, _OPEN: to be worked out ray by ray), behind the
        scene's depth `zb` over the box (None: no scene); None when the outline cannot be
        trusted (part of the board behind the camera or far off-axis)."""
        th, tw = tex_shape[:2]
        # remap's alpha is 255 for a ray that meets the texture within its outer texel centres
        # (the inner ring) and 0 beyond a texel outside them (the outer ring): bilinear weights;
        # between, its rounding decides
        lo = np.array([[[0.0, 0.0]], [[-1.0, -1.0]]])
        hi = np.array([[[tw - 1.0, th - 1.0]], [[tw, th]]])
        ab = ((lo + _SQUARE_RING * (hi - lo)).reshape(-1, 2) + 0.5) * texel
        pts = plane_left.origin + ab[:, :1] * plane_left.u + ab[:, 1:] * plane_left.v
        pc = self._to_camera(cam, pts)
        if np.any(pc[:, 2] <= 1.0) or np.any(np.hypot(pc[:, 0], pc[:, 1])
                                             > self._max_tan * pc[:, 2]):
            return None
        # a ray meets the board at depth n.o / n.r, no farther than zmax: perspectiveTransform,
        # which gives depth 0 (and texel (0, 0)) where |n.r| <= FLT_EPSILON, computes it
        zmax = float(pc[:, 2].max())
        if abs(Hz[0, 2]) <= 2 * _FLT_EPS * zmax:
            return None
        # on the supersample grid of the box; a ring is the polygon through its vertices, as far
        # from the curved image of the outline as the midpoints between them
        s = self.config.supersample
        q = (s * (self.project(pts, cam) + 0.5) - 0.5 - np.array(box[:2])).reshape(2, -1, 2)
        vertices = q[:, 0::2]
        if np.max(np.abs(q[:, 1::2] - 0.5 * (vertices + np.roll(vertices, -1, 1)))) > 0.35:
            return None
        # what lies within the outer ring or within _EDGE_PX / 2 of either ring is open, what
        # lies within the inner ring and farther from both shows the board; drawn with a margin
        # (fillPoly marks a canvas's outermost pixels for parts of a polygon beyond them)
        m = _EDGE_PX
        canvas = np.zeros((box[3] - box[1] + 2 * m, box[2] - box[0] + 2 * m), np.uint8)
        inner, outer = np.round((vertices + m) * 16).astype(np.int32)  # (1/16: shift=4)
        cv2.fillPoly(canvas, [outer], _OPEN, shift=4)
        cv2.fillPoly(canvas, [inner], 255, shift=4)
        cv2.polylines(canvas, [inner, outer], True, _OPEN, _EDGE_PX, shift=4)
        mask = canvas[m:-m, m:-m]
        if zb is not None:
            # the scene may hide the board only where it is nearer than zmax (with room for the
            # rounding of the depth to float)
            near = cv2.compare(zb, zmax * (1.0 + 1e-5), cv2.CMP_LE)  # type: ignore[call-overload]
            cv2.bitwise_and(mask, _OPEN, dst=mask, mask=near)  # type: ignore[call-overload]
        return mask

    def _object_plane(self, obj: SceneObject) -> _Plane:
        return _Plane(obj.corner_origin, obj.u, obj.v, obj.width_mm, obj.height_mm)

    def _board_plane(self, pose: BoardPose) -> _Plane:
        a0, b0, a1, b1 = self.board_outline_mm()
        origin = pose.t + pose.R @ np.array([a0, b0, 0.0])
        return _Plane(origin, pose.R[:, 0], pose.R[:, 1], a1 - a0, b1 - b0)

    def _background(self, cam: int, scene: Scene | None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Supersampled image (uint8 BGR), depth buffer and averaged image of the static scene
        for one camera (cached: the scene does not move)."""
        key = (cam, id(scene))
        with self._lock:
            hit = self._scene_cache.get(key)
            if hit is not None and hit[0] is scene:
                return hit[1:]
        s = self.config.supersample
        w, h = self.config.image_size
        img = np.full((h * s, w * s, 3), _BOARD_BACKGROUND, np.uint8)
        zbuf = np.full((h * s, w * s), np.inf, np.float32)
        if scene is not None:
            for obj in scene.objects:
                tex, texel = _texture(int(obj.seed), float(obj.width_mm), float(obj.height_mm),
                                      float(obj.contrast))
                self._draw_plane(cam, self._object_plane(obj), tex, texel, img, zbuf)
        small = img if s == 1 else cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
        with self._lock:
            if len(self._scene_cache) > 8:
                self._scene_cache.clear()
            self._scene_cache[key] = (scene, img, zbuf, small)
        return img, zbuf, small

    def _noise_bank(self, cam: int) -> np.ndarray:
        """Gaussian sensor noise around 128 (uint8), larger than an image; frames use random
        crops of it, which is much cheaper than drawing fresh noise for every pixel."""
        bank = self._noise.get(cam)
        if bank is None:
            w, h = self.config.image_size
            rng = np.random.default_rng(self.seed * 31 + cam + 99)
            noise = (rng.standard_normal((h + _NOISE_PAD, w + _NOISE_PAD, 3))
                     * self.config.noise_sigma)
            bank = np.clip(np.rint(noise + 128.0), 0, 255).astype(np.uint8)
            self._noise[cam] = bank
        return bank

    def _render_camera(self, cam: int, pose: BoardPose | None, scene: Scene | None,
                       rng: np.random.Generator, look: CameraLook | None = None) -> np.ndarray:
        """Camera `cam`'s image of the board at `pose` (None: none) and `scene`; `look`
        (sim.controls.CameraLook) is what its controls do to the image (None: as built)."""
        s = self.config.supersample
        w, h = self.config.image_size
        bg, zb, small = self._background(cam, scene)
        out = small.copy()
        if pose is not None:
            plane = self._board_plane(pose)
            box = self._bbox(cam, plane)
            if box is not None:
                # work only on the board's box, aligned to whole pixels
                x0, y0 = box[0] // s * s, box[1] // s * s
                x1, y1 = min(w * s, -(-box[2] // s) * s), min(h * s, -(-box[3] // s) * s)
                crop = bg[y0:y1, x0:x1].copy()
                # (the board is drawn last: the scene's depth is only read)
                self._draw_board(cam, plane, box, crop, (x0, y0), zb if scene is not None else None)
                part = crop if s == 1 else cv2.resize(crop, ((x1 - x0) // s, (y1 - y0) // s),
                                                      interpolation=cv2.INTER_AREA)
                out[y0 // s:y1 // s, x0 // s:x1 // s] = part
        c = self.config
        gain = 1.0 if cam == 0 else float(c.gain_right)
        black = 0.0 if cam == 0 else float(c.black_right)
        if look is not None and not look.neutral:
            out = self._apply_look(cam, out, look)
            gain *= look.gain
            black += look.offset
        if c.vignetting > 0:
            out = cv2.multiply(out, self._vignette(), dtype=cv2.CV_8U)
        if c.noise_sigma > 0:
            dx, dy = (int(v) for v in rng.integers(0, _NOISE_PAD + 1, 2))
            noise = self._noise_bank(cam)[dy:dy + h, dx:dx + w]
            img = cv2.addWeighted(out, gain, noise, 1.0, black - 128.0, dtype=cv2.CV_8U)
        else:
            img = cv2.convertScaleAbs(out, alpha=gain, beta=black)
        if c.jpeg_quality is not None:
            ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(c.jpeg_quality)])
            decoded = cv2.imdecode(data, cv2.IMREAD_COLOR)
            if decoded is None:  # (its own JPEG: only short of memory)
                raise RuntimeError("the simulated camera's JPEG does not decode")
            img = decoded
        return img

    def _apply_look(self, cam: int, img: np.ndarray, look: CameraLook) -> np.ndarray:
        """The focal length scaled about the principal point and the colour tint of `look`
        (its gain and offset are applied with the sensor's)."""
        if abs(look.focal_scale - 1.0) > 1e-9:
            M = self.truth.M1 if cam == 0 else self.truth.M2
            s, cx, cy = float(look.focal_scale), float(M[0, 2]), float(M[1, 2])
            A = np.array([[s, 0.0, (1.0 - s) * cx], [0.0, s, (1.0 - s) * cy]])
            img = cv2.warpAffine(img, A, (img.shape[1], img.shape[0]), flags=cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_REPLICATE)
        if look.channels != (1.0, 1.0, 1.0):
            img = cv2.multiply(img, (*look.channels, 0.0), dtype=cv2.CV_8U)
        return img

    def _vignette(self) -> np.ndarray:
        """Per-pixel brightness factor (float32, 3 channels) of the lens's darker corners: 1 in
        the centre, 1 - vignetting in the corners, quadratic in the distance between."""
        v = self._noise.get("vignette")
        if v is None:
            w, h = self.config.image_size
            y, x = np.mgrid[0:h, 0:w].astype(np.float32)
            r2 = ((x - (w - 1) / 2) ** 2 + (y - (h - 1) / 2) ** 2) / (((w - 1) / 2) ** 2
                                                                      + ((h - 1) / 2) ** 2)
            f = (1.0 - self.config.vignetting * r2).astype(np.float32)
            v = cv2.merge([f, f, f])
            self._noise["vignette"] = v
        return v

    def _render(self, pose: BoardPose | None, scene: Scene | None,
                rng: np.random.Generator | None) -> tuple[np.ndarray, np.ndarray]:
        rng = rng if rng is not None else np.random.default_rng()
        return self._render_camera(0, pose, scene, rng), self._render_camera(1, pose, scene, rng)

    def render_board_pair(self, pose: BoardPose, rng: np.random.Generator | None = None,
                          scene: Scene | None = None,
                          pose_right: BoardPose | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Left and right BGR uint8 (h, w, 3) images of the board at `pose` (optionally in front
        of a scene); the right camera sees it at `pose_right` where that is given (a board that
        moved between two unsynchronised grabs)."""
        if pose_right is None:
            return self._render(pose, scene, rng)
        rng = rng if rng is not None else np.random.default_rng()
        return (self._render_camera(0, pose, scene, rng),
                self._render_camera(1, pose_right, scene, rng))

    def calibration_set(self, n_pairs: int, seed: int | None = None
                        ) -> list[tuple[np.ndarray, np.ndarray]]:
        """`n_pairs` rendered board pairs at varied poses (deterministic for the rig's seed)."""
        rng = np.random.default_rng(self.seed * 104729 + 5 if seed is None else seed)
        return [self.render_board_pair(p, rng) for p in self.board_poses(n_pairs, seed)]

    def render_scene(self, scene: Scene, rng: np.random.Generator | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Left and right BGR uint8 images of a scene."""
        return self._render(None, scene, rng)

    # ---- ground truth for the pipeline --------------------------------------------------
    def true_calibration(self, alpha: float = 0.0) -> StereoCalibration:
        """The calibration a perfect calibration would find (Bouguet rectification)."""
        t = self.truth
        size = (int(t.image_size[0]), int(t.image_size[1]))
        R1, R2, P1, P2, Q = stereo_rectify(t.model, t.M1, t.D1, t.M2, t.D2, size, t.R, t.T, alpha)
        tx = t.T.reshape(3)
        Tx = np.array([[0, -tx[2], tx[1]], [tx[2], 0, -tx[0]], [-tx[1], tx[0], 0]], np.float64)
        E = Tx @ t.R
        F = np.linalg.inv(t.M2).T @ E @ np.linalg.inv(t.M1)
        F = F / F[2, 2]
        return StereoCalibration(size, t.M1.copy(), t.D1.copy(), t.M2.copy(), t.D2.copy(),
                                 t.R.copy(), t.T.copy(), E, F, R1, R2, P1, P2, Q, board=t.board,
                                 rms_left=0.0, rms_right=0.0, rms_stereo=0.0,
                                 epipolar_error_px=0.0, method="bouguet", alpha=float(alpha),
                                 model=t.model, origin="the simulated rig's truth",
                                 lens_shading=self.true_shading())

    def true_shading(self) -> PairShading | None:
        """Both cameras' true lens shading (core.shading.PairShading), None without vignetting:
        the rig darkens both cameras' corners alike, 1 - vignetting * r^2 of the raw image,
        before each camera's gain and black level."""
        v = float(self.config.vignetting)
        if v <= 0.0:
            return None
        return PairShading(LensShading(-v, 0.0, 0.0),
                           LensShading(-v, 0.0, float(self.config.black_right)))

    def true_point_rectified(self, calib: StereoCalibration, scene: Scene, x: float, y: float
                             ) -> np.ndarray | None:
        """True (X, Y, Z) mm in the left rectified frame of `calib` seen at rectified pixel
        (x, y), or None if the ray hits nothing."""
        ray_rect = np.linalg.inv(np.asarray(calib.P1, np.float64)[:, :3]) @ np.array([x, y, 1.0])
        R1 = np.asarray(calib.R1, np.float64)
        ray_left = R1.T @ ray_rect
        ray_left /= np.linalg.norm(ray_left)
        t = scene.depth_along_ray(np.zeros(3), ray_left)
        if t is None:
            return None
        point: np.ndarray = R1 @ (t * ray_left)
        return point
