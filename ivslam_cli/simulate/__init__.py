"""Synthetic logs with ground truth: ``ivslam simulate``.

Three scenarios (:func:`simulate` dispatches on ``SimConfig.scenario``):

- ``pairs``: holonomic robot that never rotates (true heading 0, bound ``heading`` = 0)
  among point landmarks; range and bearing of every landmark within ``[min_range,
  max_range]`` all around; every step sees at least two landmarks, at least one of them
  already seen at an earlier step (landmarks are added by construction where needed and
  the property is checked). No odometry (the pairs method of
  Mustafa, Codres & Stancu needs none).
- ``landmarks``: unicycle robot (v, omega) with twist odometry, landmarks seen within a
  field of view ``|bearing| <= fov`` and ``[min_range, max_range]`` (MRCLAM's camera:
  fov 0.6 rad, 0.9-8 m).
- ``lidar``: unicycle robot in a world of wall segments (:mod:`.worlds`), 2D LiDAR
  (:mod:`.sensors`: ``urg-04lx``, ``sick``) with cone or ray beams (below), twist odometry.

Noise bound keys (config-style names, reused by the pipelines' config; all half-widths,
the error ``e = z - g(truth)`` of an in-bound measurement satisfies ``|e| <= bound``):

==============  =====================================================================
``range_abs``   range error, absolute part [m]
``range_rel``   range error, part proportional to the range [m/m]: for landmark
                observations the measured one, as the pipelines read it
                (``|z_range - rho| <= range_abs + range_rel * z_range``); for LiDAR
                beams the true one (``... + range_rel * rho``; the lidar pipeline
                converts, covering both)
``bearing``     bearing error [rad], on the circle: ``|wrap(z - alpha)| <= bearing``
``heading``     (pairs) the known heading interval half-width around 0 [rad]
``odom_v``      twist linear speed error, absolute part [m/s]
``odom_v_rel``  ... proportional to the true speed [(m/s)/(m/s)]:
                ``|z_v - v| <= odom_v + odom_v_rel * |v|``
``odom_w``      twist angular speed error, absolute part [rad/s]
``odom_w_rel``  ... proportional to distance travelled [rad/m]:
                ``|z_w - w| <= odom_w + odom_w_rel * |v|``
``beam_angle``  LiDAR bearing bound [rad] (read as ``bearing`` by the pipelines): the
                cone half-width ``h`` of the cone model (default: half the beam step;
                with a sweep, wide enough that adjacent cones overlap by the turn
                between two beams: ``config.swept_half_width``);
                with the ray model only stated, rays being exact (default 0)
==============  =====================================================================

LiDAR beam models (``SimConfig.beam_model``, ``--beam-model``; recorded as
``meta["beam_model"]``). Beam ``i`` of a scan has the nominal angle ``a_i = angle_min + i
* angle_increment`` (float64 arithmetic on the stored float32 values) in the laser frame;
its true distance ``d`` is, with ``e(d) = range_abs + range_rel * d``:

- ``cone`` (default): the distance from the sensor to the nearest wall point within the
  closed sector ``[a_i - h, a_i + h]`` (:mod:`.conecast`; ``inf`` if none), ``h`` the
  stated ``beam_angle``. Guarantees, for an in-bound valid return ``z``: ``|z - d| <=
  e(d)``, a wall point at distance ``d`` lies within ``+-h`` of ``a_i``, and every point of
  the sector closer than ``d`` is free. ``h`` is at least half the beam step (the default is
  the smallest double with ``2 h >= angle_increment``; a smaller ``beam_angle`` is refused),
  so the sectors of adjacent beams touch and a scan proves free space without the
  ``lidar.fill_gaps`` assumption (the pipeline's test ``angle_increment > 2 * bearing`` for
  gaps is false on these logs).
- ``ray``: the distance along the ray at exactly ``a_i`` to the first wall it meets
  (:mod:`.raycast`). Guarantees ``|z - d| <= e(d)`` and a wall point at distance ``d`` on
  that ray; nothing about the space between two rays, so with the default ``beam_angle``
  = 0 a scan proves no free space unless the reader assumes ``lidar.fill_gaps``.

Both models draw the same random numbers in the same order: for one seed the trajectory,
the odometry and the noise draws are the same, only the true distances (and what follows
from them: ranges, valid beams) differ.

Bound semantics are exact in floating point: in-bound errors are drawn inside
``INSIDE * bound`` (``INSIDE = 0.999``), so the residual recomputed from the written
values (float32 LaserScan ranges included) is still inside ``bound``; the generator checks
this before returning. Distributions (``noise``): ``uniform`` (default), ``triangular``
(mode 0), ``edges`` (``+-INSIDE * bound``, the worst case for soundness tests).

Gross outliers (``outlier_rate``, ``outlier_magnitude`` = a multiple of the bound) have
``|e| = bound * (1 + U(0.1, 1) * magnitude)``; wrong associations relabel an observation
with another landmark whose prediction is out of bounds. Both are recorded in
``GroundTruth.outliers[stream]`` (True = breaks the stated bounds), and only those break
them. LiDAR outliers are phantom returns (short of the true range, or a return where
there is none).

Motion model (twist odometry): the twist at stamp ``t_k`` is the constant (v, omega)
over ``[t_k, t_{k+1})``; ``s_{k+1} = h(s_k, u_k, t_{k+1} - t_k)`` with the exact arc
(:func:`.motion.unicycle_step`). True poses are at the odometry stamps, the initial pose
is known exactly (odometry frame = world frame at ``t_0``).

Time: every stamp lies on a 1/512 s grid (``t_0`` = 1.7e9 s), so float seconds, ROS
``(sec, nanosec)`` and MCAP nanoseconds are exact images of each other.
"""

from __future__ import annotations

from ivslam_cli.simulate.config import SimConfig

__all__ = ["SimConfig", "simulate"]


def simulate(config: SimConfig, progress=None):
    """Run the scenario of ``config``; returns a :class:`~ivslam_cli.logs.model.LogData`.

    ``progress(n)`` (optional) is called with the number of steps just completed.
    """
    config.validate()
    if config.scenario == "pairs":
        from ivslam_cli.simulate.pairs import simulate_pairs as run
    elif config.scenario == "landmarks":
        from ivslam_cli.simulate.landmarks import simulate_landmarks as run
    else:
        from ivslam_cli.simulate.lidar import simulate_lidar as run
    return run(config, progress)
