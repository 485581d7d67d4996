"""The video of a MuJoCo run (SPEC 16): :func:`render_frames` draws ``(t, qpos)`` frames of the
exported MJCF offscreen, with the first OpenGL backend that works (``MUJOCO_GL`` when set, else
EGL, then OSMesa) and notes on those that did not. The run itself is :mod:`.mujoco_run`.
"""

from __future__ import annotations

import ctypes.util
import importlib
import os
from collections.abc import Sequence

import numpy as np

from .mjcf import ContactModel
from .mujoco_run import MujocoModel, load_mujoco

RENDERERS = ("egl", "osmesa")  # offscreen OpenGL, tried in this order unless MUJOCO_GL is set


def _backends() -> tuple[list[str], list[str]]:
    """Offscreen OpenGL backends to try, and notes on the ones skipped."""
    chosen = os.environ.get("MUJOCO_GL", "").strip().lower()
    if chosen:
        return [chosen], [f"MUJOCO_GL={chosen} (set in the environment)"]
    out, notes = [], []
    for name, lib in (("egl", "EGL"), ("osmesa", "OSMesa")):
        if ctypes.util.find_library(lib):
            out.append(name)
        else:
            notes.append(f"{name}: lib{lib} not found")
    return out, notes


def render_frames(robot, contact: ContactModel, mu: float,
                  frames: Sequence[tuple[float, list[float]]], *, width: int = 480,
                  height: int = 360) -> tuple[list[np.ndarray], str | None, list[str]]:
    """Render ``(t, qpos)`` frames of the MJCF offscreen (RGB ``(height, width, 3)`` uint8
    arrays, the camera beside the plane following the robot's centre of mass), with the
    first offscreen OpenGL backend that works (``MUJOCO_GL`` when set, else EGL, then
    OSMesa). Returns ``(images, backend, notes)``: no images and ``backend`` None when none
    works, ``notes`` saying what was tried and why it failed. Shadows and reflections are off
    (software rendering)."""
    mj = load_mujoco()
    sim = MujocoModel(robot, contact, mu)
    m, d = sim.m, sim.d
    tried, notes = _backends()
    notes = list(notes)
    for name in tried:
        if name not in RENDERERS:
            notes.append(f"{name}: not an offscreen backend (use egl or osmesa)")
            continue
        ctx = con = None
        try:
            ctx = importlib.import_module(f"mujoco.{name}").GLContext(width, height)
            ctx.make_current()
            con = mj.MjrContext(m, mj.mjtFontScale.mjFONTSCALE_150.value)
            mj.mjr_setBuffer(mj.mjtFramebuffer.mjFB_OFFSCREEN.value, con)
            scn = mj.MjvScene(m, maxgeom=200)
            for flag in (mj.mjtRndFlag.mjRND_SHADOW, mj.mjtRndFlag.mjRND_REFLECTION,
                         mj.mjtRndFlag.mjRND_SKYBOX):
                scn.flags[flag] = False
            cam, opt = mj.MjvCamera(), mj.MjvOption()
            cam.type = mj.mjtCamera.mjCAMERA_FREE
            extent = float(m.stat.extent)
            cam.distance, cam.azimuth, cam.elevation = 1.6 * extent, 90.0, -8.0
            rect = mj.MjrRect(0, 0, width, height)
            images = []
            for _, qpos in frames:
                d.qpos[:] = qpos
                mj.mj_forward(m, d)
                com = d.subtree_com[1]
                cam.lookat[:] = [com[0], 0.0, 0.45 * extent]
                mj.mjv_updateScene(m, d, opt, None, cam, mj.mjtCatBit.mjCAT_ALL.value, scn)
                mj.mjr_render(rect, scn, con)
                buf = np.empty((height, width, 3), np.uint8)
                mj.mjr_readPixels(buf, None, rect, con)
                images.append(np.flipud(buf).copy())
            return images, name, notes
        except Exception as exc:  # no device, no library, a PyOpenGL platform already bound
            notes.append(f"{name}: {type(exc).__name__}: {exc}".replace("\n", " "))
        finally:
            if con is not None:
                con.free()
            if ctx is not None:
                ctx.free()
    return [], None, notes
