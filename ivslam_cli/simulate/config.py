"""Simulation options with per-scenario defaults, validated in one place."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from ivslam_cli.errors import ConfigError

SCENARIOS = ("pairs", "landmarks", "lidar")
NOISES = ("uniform", "triangular", "edges")
BEAM_MODELS = ("cone", "ray")

#: Default noise bounds per scenario (half-widths, see the package docstring). The lidar
#: ``beam_angle`` is that of the ray model; the cone model's default is half the sensor's
#: beam step (:meth:`~ivslam_cli.simulate.sensors.LidarProfile.half_step`).
DEFAULT_BOUNDS: dict[str, dict[str, float]] = {
    "pairs": {"range_abs": 0.05, "range_rel": 0.0, "bearing": 0.02, "heading": 0.0},
    "landmarks": {
        "range_abs": 0.05, "range_rel": 0.01, "bearing": 0.02,
        "odom_v": 0.01, "odom_v_rel": 0.05, "odom_w": 0.01, "odom_w_rel": 0.05,
    },
    "lidar": {
        "range_abs": 0.03, "range_rel": 0.01, "beam_angle": 0.0,
        "odom_v": 0.01, "odom_v_rel": 0.05, "odom_w": 0.01, "odom_w_rel": 0.05,
    },
}

#: The simulated robot's top turn rate [rad/s] (the lidar scenario's wanderer).
TURN_RATE_MAX = 1.0
#: A swept simulated scan proves free space from this far of its sensor on, by default [m].
SWEEP_FREE_FROM = 0.1

#: Default (steps, rate [Hz]) per scenario.
DEFAULT_STEPS = {"pairs": 200, "landmarks": 500, "lidar": 300}
DEFAULT_RATE = {"pairs": 5.0, "landmarks": 10.0, "lidar": None}  # lidar: the sensor's rate


def swept_half_width(prof, sweep: float, speed: float) -> float:
    """The cone half-width ``h`` a swept scan needs to prove free space from ``SWEEP_FREE_FROM``.

    Between two beams (``c = sweep / (beams - 1)`` apart) the sensor turns by at most
    ``eta = TURN_RATE_MAX c`` and moves by at most ``delta = (speed + TURN_RATE_MAX |mount|) c``;
    adjacent cones then certify free space from ``(pi/3) delta / (2h - step - eta)`` of the
    sensor on (``free_cones.sweep_free_from``). The least ``h`` with that distance at most
    ``SWEEP_FREE_FROM``, rounded up; half the beam step is too narrow: its cones only touch.
    """
    c = sweep / (prof.beams - 1)
    eta = TURN_RATE_MAX * c
    delta = (speed + TURN_RATE_MAX * math.hypot(prof.mount[0], prof.mount[1])) * c
    h = prof.half_step() + 0.5 * (eta + (math.pi / 3.0) * delta / SWEEP_FREE_FROM)
    up = math.ceil(h * 1e5) / 1e5  # a readable value, at least h
    return up if up >= h else math.nextafter(h, math.inf)


@dataclass
class SimConfig:
    """Everything that determines a simulated log (same config + seed = same log)."""

    scenario: str = "pairs"
    seed: int = 0
    steps: int | None = None
    duration: float | None = None  # seconds; alternative to steps
    rate: float | None = None  # Hz of steps (observations, odometry, scans)
    landmarks: int = 30
    world_size: float = 20.0  # side of the square landmark world [m]
    world: str = "rooms"  # built-in name or a file (lidar)
    sensor: str = "urg-04lx"  # lidar profile
    beam_model: str = "cone"  # lidar: "cone" (nearest wall within +-beam_angle) or "ray"
    min_range: float | None = None
    max_range: float | None = None
    fov: float | None = None  # half field of view [rad] (landmarks)
    speed: float = 0.5  # nominal linear speed [m/s]
    sweep: float = 0.0  # lidar: seconds from a scan's stamp (its first beam) to its last beam
    noise: str = "uniform"
    bounds: dict[str, float] = field(default_factory=dict)  # overrides of DEFAULT_BOUNDS
    outlier_rate: float = 0.0
    outlier_magnitude: float = 10.0
    wrong_association_rate: float = 0.0

    # ---- resolved values -------------------------------------------------------
    def resolved_bounds(self) -> dict[str, float]:
        out = dict(DEFAULT_BOUNDS[self.scenario])
        for key, value in self.bounds.items():
            if value is None:
                continue
            if key not in out:
                raise ConfigError(f"bound '{key}' does not apply to scenario '{self.scenario}'")
            out[key] = float(value)
        if self.scenario == "lidar" and self.beam_model == "cone" and self.bounds.get("beam_angle") is None:
            from ivslam_cli.simulate.sensors import get_profile

            prof = get_profile(self.sensor)
            out["beam_angle"] = (prof.half_step() if self.sweep <= 0.0
                                 else swept_half_width(prof, self.sweep, self.speed))
        return out

    def resolved_rate(self, sensor_rate: float | None = None) -> float:
        if self.rate is not None:
            return float(self.rate)
        return float(DEFAULT_RATE[self.scenario] or sensor_rate or 10.0)

    def resolved_steps(self, rate: float) -> int:
        if self.steps is not None:
            return int(self.steps)
        if self.duration is not None:
            return max(1, int(round(self.duration * rate)))
        return DEFAULT_STEPS[self.scenario]

    def range_limits(self) -> tuple[float, float]:
        lo, hi = {"pairs": (0.5, 6.0), "landmarks": (0.9, 8.0)}.get(self.scenario, (0.0, math.inf))
        return (lo if self.min_range is None else self.min_range,
                hi if self.max_range is None else self.max_range)

    def half_fov(self) -> float:
        if self.fov is not None:
            return float(self.fov)
        return math.pi if self.scenario == "pairs" else 0.6

    def as_dict(self) -> dict:
        return asdict(self)

    # ---- validation --------------------------------------------------------------
    def validate(self) -> None:
        """Raise :class:`ConfigError` (one line) on any inconsistent value."""
        if self.scenario not in SCENARIOS:
            raise ConfigError(f"unknown scenario '{self.scenario}' (choose from {', '.join(SCENARIOS)})")
        if self.noise not in NOISES:
            raise ConfigError(f"unknown noise '{self.noise}' (choose from {', '.join(NOISES)})")
        if self.beam_model not in BEAM_MODELS:
            raise ConfigError(f"unknown beam model '{self.beam_model}' (choose from {', '.join(BEAM_MODELS)})")
        if not (math.isfinite(self.sweep) and self.sweep >= 0.0):
            raise ConfigError(f"--sweep must be a finite time >= 0, got {self.sweep}")
        if self.sweep > 0.0 and (self.scenario != "lidar" or self.beam_model != "cone"):
            raise ConfigError("--sweep applies to the lidar scenario with the cone beam model")
        if self.steps is not None and self.steps < 2:
            raise ConfigError(f"--steps must be >= 2, got {self.steps}")
        if self.steps is not None and self.duration is not None:
            raise ConfigError("give --steps or --duration, not both")
        if self.duration is not None and not self.duration > 0:
            raise ConfigError(f"--duration must be > 0, got {self.duration}")
        if self.rate is not None and not (0 < self.rate <= 256):
            raise ConfigError(f"--rate must be in (0, 256] Hz, got {self.rate}")
        if self.landmarks < 1 and self.scenario != "lidar":
            raise ConfigError(f"--landmarks must be >= 1, got {self.landmarks}")
        if not self.world_size > 2:
            raise ConfigError(f"--world-size must be > 2 m, got {self.world_size}")
        if not self.speed > 0:
            raise ConfigError(f"--speed must be > 0, got {self.speed}")
        for name in ("outlier_rate", "wrong_association_rate"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ConfigError(f"--{name.replace('_', '-')} must be in [0, 1], got {value}")
        if not self.outlier_magnitude > 0:
            raise ConfigError(f"--outlier-magnitude must be > 0, got {self.outlier_magnitude}")
        for key, value in self.resolved_bounds().items():
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"bound '{key}' must be finite and >= 0, got {value}")
        bounds = self.resolved_bounds()
        if "range_rel" in bounds and bounds["range_rel"] >= 0.5:
            raise ConfigError(f"bound 'range_rel' must be < 0.5, got {bounds['range_rel']}")
        if "bearing" in bounds and bounds["bearing"] >= 0.5:
            raise ConfigError(f"bound 'bearing' must be < 0.5 rad, got {bounds['bearing']}")
        if self.scenario == "lidar":
            from ivslam_cli.simulate.sensors import get_profile
            from ivslam_cli.simulate.worlds import load_world

            prof = get_profile(self.sensor)
            load_world(self.world)
            h = bounds["beam_angle"]
            if self.beam_model == "cone" and not 2.0 * h >= prof.angle_increment:
                raise ConfigError(f"--beam-angle {h:g} is below half the beam step of {prof.name} "
                                  f"({prof.half_step():.17g} rad): cone beams that narrow leave gaps "
                                  "between them; give at least that, or --beam-model ray")
            if self.beam_model == "cone" and not h < 0.5:
                raise ConfigError(f"--beam-angle must be < 0.5 rad for the cone model, got {h:g}")
        else:
            lo, hi = self.range_limits()
            if not (0 <= lo < hi and math.isfinite(hi)):
                raise ConfigError(f"need 0 <= --min-range < --max-range, got {lo}, {hi}")
            if not 0 < self.half_fov() <= math.pi:
                raise ConfigError(f"--fov must be in (0, pi], got {self.half_fov()}")
