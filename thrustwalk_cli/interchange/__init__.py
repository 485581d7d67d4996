"""Robots to and from other tools' formats (SPEC 16): ``urdf`` (URDF -> robot YAML, and a
thrustwalk robot -> planar URDF). Files are read by ``files/`` (``files/urdf_file.py``);
this unit does the mechanics."""
