"""2D LiDAR profiles.

Every geometric field is a float32 value (LaserScan stores float32), kept as the float64
image of that float32 so logs round-trip exactly.

- ``urg-04lx`` (Hokuyo URG-04LX, the sensor of the Guaranteed SLAM slides): 682 beams,
  360/1024 deg apart (239.4 deg), 10 Hz, 0.02-5.6 m. No-return beams are written as ``0.0``
  (the URG error-code convention: any value below ``range_min`` is not a return).
- ``sick`` (SICK LMS-like): 180 beams over 180 deg (1 deg apart, 179 deg span), 5 Hz,
  0.05-30 m. No-return beams follow REP 117: ``+inf`` (nothing within range_max),
  ``-inf`` (too close).

A noisy range that falls outside ``[range_min, range_max]`` is written as a no-return,
as a driver would: a no-return beam therefore guarantees only that the true distance
``d`` satisfies ``d + e(d) > range_max`` (free space up to ``range_max - e``), with
``e(d) = range_abs + range_rel * d``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ivslam_cli.errors import ConfigError


def f32(x: float) -> float:
    return float(np.float32(x))


@dataclass(frozen=True)
class LidarProfile:
    name: str
    beams: int
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    rate: float
    no_return: str  # "zero" or "inf"
    mount: tuple[float, float, float]

    def beam_angles(self) -> np.ndarray:
        """Nominal beam angles in the laser frame, float64: ``angle_min + i * increment``."""
        return self.angle_min + np.arange(self.beams) * self.angle_increment

    def half_step(self) -> float:
        """The smallest double ``h`` with ``2 h >= angle_increment`` (the float64 image of the
        float32 a LaserScan stores): cones of that half-width touch their neighbours'."""
        inc = float(np.float32(self.angle_increment))
        if inc != self.angle_increment:  # pragma: no cover - _profile stores float32 images
            raise ValueError(f"profile '{self.name}': angle_increment is not a float32 value")
        h = 0.5 * inc
        while 2.0 * h < inc:
            h = float(np.nextafter(h, np.inf))
        while 2.0 * float(np.nextafter(h, -np.inf)) >= inc:
            h = float(np.nextafter(h, -np.inf))
        return h

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__} | {"mount": list(self.mount)}


def _profile(name, beams, increment, range_min, range_max, rate, no_return, mount):
    inc = f32(increment)
    return LidarProfile(name, beams, f32(-0.5 * (beams - 1) * inc), inc, f32(range_min),
                        f32(range_max), rate, no_return, mount)


PROFILES = {
    "urg-04lx": _profile("urg-04lx", 682, 2 * math.pi / 1024, 0.02, 5.6, 10.0, "zero", (0.1, 0.0, 0.0)),
    "sick": _profile("sick", 180, math.pi / 180, 0.05, 30.0, 5.0, "inf", (0.15, 0.0, 0.0)),
}


def get_profile(name: str) -> LidarProfile:
    try:
        return PROFILES[name]
    except KeyError:
        raise ConfigError(f"unknown sensor '{name}' (choose from {', '.join(PROFILES)})") from None
