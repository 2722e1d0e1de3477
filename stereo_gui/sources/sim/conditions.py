"""How the simulated rig renders a wall: the rig's usual rich texture, a smooth painted wall at
lower contrast, and what two cheap webcams add (the right camera's own gain and black level,
darker corners, MJPG compression). `stereo-gui bench --accuracy --condition C` measures each one;
`--source sim:wall:C[:METRES]` shows it in the window."""

from __future__ import annotations

from dataclasses import dataclass, replace

from stereo_gui.core.errors import InputError
from stereo_gui.sources.sim.camera import RigConfig


@dataclass(frozen=True)
class Condition:
    """How a wall is rendered: its texture's contrast (1: the rig's usual texture), the sensor
    noise (grey levels), and the webcam effects of `RigConfig` (right camera's gain and black
    level, vignetting, JPEG quality)."""

    name: str
    contrast: float = 1.0
    noise_sigma: float | None = None  # None: the rig's own
    gain_right: float | None = None
    black_right: float = 0.0
    vignetting: float = 0.0
    jpeg_quality: int | None = None
    description: str = ""
    label: str = ""  # a few words for a menu

    @property
    def changes_cameras(self) -> bool:
        """Whether the condition changes what the cameras do to any image (a calibration made
        with them differs), not only the wall."""
        return bool(self.gain_right is not None or self.black_right or self.vignetting
                    or self.jpeg_quality is not None)

    def rig_config(self, base: RigConfig) -> RigConfig:
        """`base` (a RigConfig) with this condition's sensor and webcam effects."""
        return replace(
            base, black_right=self.black_right, vignetting=self.vignetting,
            jpeg_quality=self.jpeg_quality,
            noise_sigma=base.noise_sigma if self.noise_sigma is None else self.noise_sigma,
            gain_right=base.gain_right if self.gain_right is None else self.gain_right)


# a painted wall: a 9x9 window's grey-level spread about 2.5 with the sensor noise of 1.5
WEAK_CONTRAST = 0.12
CONDITIONS = {c.name: c for c in (
    Condition("rig", description="the rig's usual texture", label="a richly textured wall"),
    Condition("weak", WEAK_CONTRAST, 1.5, description="a smooth painted wall: 9x9 spread ~2.5 "
              "grey levels with noise 1.5", label="a smooth painted wall"),
    Condition("half", WEAK_CONTRAST / 2, 1.5, description="the painted wall at half contrast",
              label="a painted wall at half contrast"),
    Condition("quarter", WEAK_CONTRAST / 4, 1.5,
              description="the painted wall at a quarter of its contrast",
              label="a painted wall at a quarter of its contrast"),
    Condition("webcams", WEAK_CONTRAST / 2, 1.5, gain_right=0.8, black_right=12.0,
              vignetting=0.35, jpeg_quality=75,
              description="half contrast, the right camera's gain 0.8 and black level +12, "
              "corners 35 % darker, MJPG at quality 75",
              label="a painted wall (half) through two cheap webcams"),
    # the webcam effects one at a time, at half contrast: which of them costs what
    Condition("exposure", WEAK_CONTRAST / 2, 1.5, gain_right=0.8, black_right=12.0,
              description="half contrast, the right camera's gain 0.8 and black level +12",
              label="a painted wall (half), exposures that differ"),
    Condition("vignetting", WEAK_CONTRAST / 2, 1.5, vignetting=0.35,
              description="half contrast, corners 35 % darker in both cameras",
              label="a painted wall (half), darker corners"),
    Condition("mjpg", WEAK_CONTRAST / 2, 1.5, jpeg_quality=75,
              description="half contrast, MJPG at quality 75",
              label="a painted wall (half), MJPG blocks"),
)}


def condition_named(name: str) -> Condition:
    """The condition called `name`; InputError naming the choices for any other."""
    try:
        return CONDITIONS[name]
    except KeyError:
        raise InputError(f"no wall condition {name!r}: choose one of "
                         f"{', '.join(CONDITIONS)}") from None
