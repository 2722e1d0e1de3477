"""The simulated stereo rig: two distorted pinhole cameras with known truth, rendering a chessboard
and textured planar objects. It is a frame source, the demo, and the ground truth of the tests.

Rendering goes through OpenCV's distortion model exactly: for each camera a ray map holds, for
every supersample of every output pixel, the normalised undistorted ray (x, y, 1) obtained by
inverting the distortion model (Newton iteration, checked against cv2.projectPoints). Each frame
intersects those rays with the planes of the board and scene, looks up the texture, and averages
the supersamples (anti-aliasing). Frames: the left camera frame is the world frame; a point X_left
maps to the right camera as X_right = R @ X_left + T (R_right_left, T_right_left, mm), the same
convention as cv2.stereoCalibrate.

The package, by room: `camera` (the rig's description and truth), `rays` (distortion inversion,
ray maps), `textures` (board and object textures), `scene` (board poses, scene objects),
`rig` (SimRig: poses, rendering, ground truth), `calibration_set` (sets on disk with
truth.json), `click_scenes` (rectified scenes with their true disparity, for `bench --clicks`),
`controls` (the cameras' controls and what they do to the images), `conditions` (how
a wall is rendered: weak texture, webcam effects) and `live` (SimSource). Every public name is importable from here.
"""

from stereo_gui.sources.sim.calibration_set import (
    HAND_SPEED_MM_S,
    HAND_SPIN_RAD_S,
    SCENE_FOLDER,
    SCENE_WALL_DISTANCES_MM,
    calibration_set_names,
    write_calibration_set,
)
from stereo_gui.sources.sim.camera import (
    TRUTH_FORMAT_VERSION,
    CameraTruth,
    RigConfig,
    RigTruth,
    load_truth,
)
from stereo_gui.sources.sim.click_scenes import (
    CLICK_CONDITIONS,
    CLICK_FOLDER,
    CLICK_LIST,
    CLICK_SUFFIXES,
    CLICK_WALLS_MM,
    MAX_CLICK_SEEDS,
    ClickScene,
    centre_check,
    click_scene_names,
    click_scene_plan,
    encode_pfm,
    rectified_spec,
    true_disparity,
    write_click_scenes,
)
from stereo_gui.sources.sim.conditions import CONDITIONS, WEAK_CONTRAST, Condition, condition_named
from stereo_gui.sources.sim.controls import (
    AUTO_TARGET,
    AUTO_WB_K,
    AUTOFOCUS_RATE,
    FOCAL_CHANGE_PER_STEP,
    MAX_AUTO_EXPOSURE,
    NEUTRAL_WB_K,
    REFERENCE_EXPOSURE,
    SIM_CONVENTION,
    TRUE_FOCUS,
    CameraLook,
    SimCameraDevice,
    sim_controls,
)
from stereo_gui.sources.sim.live import SimSource
from stereo_gui.sources.sim.rays import RayMap, ray_map, undistort_normalized
from stereo_gui.sources.sim.rig import MIN_POINT_SPACING_PX, BoardOutOfView, SimFrameTruth, SimRig
from stereo_gui.sources.sim.scene import BoardPose, Scene, SceneObject
from stereo_gui.sources.sim.textures import OCTAVES

__all__ = [
    "AUTO_TARGET", "AUTO_WB_K", "AUTOFOCUS_RATE", "FOCAL_CHANGE_PER_STEP", "MAX_AUTO_EXPOSURE",
    "NEUTRAL_WB_K", "REFERENCE_EXPOSURE", "SIM_CONVENTION", "TRUE_FOCUS", "CameraLook",
    "SimCameraDevice", "sim_controls", "CONDITIONS", "WEAK_CONTRAST", "Condition", "condition_named",
    "HAND_SPEED_MM_S", "HAND_SPIN_RAD_S", "MIN_POINT_SPACING_PX", "OCTAVES", "SCENE_FOLDER", "SCENE_WALL_DISTANCES_MM", "TRUTH_FORMAT_VERSION", "BoardOutOfView",
    "BoardPose",
    "CameraTruth", "RayMap", "RigConfig", "RigTruth", "Scene", "SceneObject", "SimFrameTruth",
    "SimRig", "SimSource", "calibration_set_names", "load_truth", "ray_map",
    "undistort_normalized", "write_calibration_set",
    "CLICK_CONDITIONS", "CLICK_FOLDER", "CLICK_LIST", "CLICK_SUFFIXES", "CLICK_WALLS_MM",
    "MAX_CLICK_SEEDS", "ClickScene", "centre_check", "click_scene_names", "click_scene_plan",
    "encode_pfm", "rectified_spec", "true_disparity", "write_click_scenes",
]
