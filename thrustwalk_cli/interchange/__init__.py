"""Robots to and from other tools' formats (SPEC 16): ``urdf`` (URDF -> robot YAML, and a
thrustwalk robot -> planar URDF), ``mjcf`` (a robot -> MuJoCo MJCF text and its coordinate
map), ``mujoco_run`` (the gait's controller on MuJoCo's soft contact; the only module that
imports mujoco) and ``mujoco_video`` (its offscreen video frames). Files are read by
``files/`` (``files/urdf_file.py``); this unit does the mechanics."""
