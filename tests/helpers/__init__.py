"""What the tests share (tests never import other test modules; see each module).

- ``paths``: REPO, DATASETS (``../shared/datasets`` or ``$IVSLAM_DATASETS``), SAMPLE_LOGS, CONFIGS;
- ``hyp``: the Hypothesis profiles (``IVSLAM_HYPOTHESIS=dev|ci|soak``), ``examples(ci=N)`` and
  ``seeds(ci=N)``, which scale a test's own count with the profile;
- ``strategies``: pose boxes around true poses (relative poses, report relations);
- ``lidar_world``: random wall worlds, the cone LiDAR, pose boxes holding the truth, the
  cell/segment truth check (map update, contraction, pipeline);
- ``ros_logs``: small LaserScan MCAP / ROS 1 bags written with the real writers (also used by
  ``bench/bench_readers.py``);
- ``ros_messages``: decoding MCAP / bags from their embedded definitions only;
- ``results``: deep equality of results.
"""
