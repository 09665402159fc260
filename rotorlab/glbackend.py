"""MuJoCo's OpenGL backend for offscreen rendering, chosen before MuJoCo loads.

MuJoCo reads ``MUJOCO_GL`` once, when ``mujoco`` is first imported, and without it uses GLFW, which needs a display.
On a Linux machine without one (a server, CI, a container) ``import rotorlab`` therefore picks a headless backend
itself: EGL where its library and a vendor driver are installed, else OSMesa where its library is, else none. A
``MUJOCO_GL`` the user set, a machine with a display and a process that imported MuJoCo before rotorlab are left
alone. Where no backend works, :func:`render_modes` declares no render mode (so ``gymnasium``'s ``check_env``
checks the environments without rendering) and :func:`renderer` raises :class:`RenderingUnavailable` saying what
to install; nothing else in rotorlab needs OpenGL.

This module must not import MuJoCo: ``rotorlab/__init__.py`` calls :func:`select` before any module that does.
"""

from __future__ import annotations

import ctypes
import os
import sys
from pathlib import Path

from rotorlab.errors import RotorlabError

__all__ = ["BACKENDS", "RenderingUnavailable", "choose", "render_modes", "renderer", "require", "select"]

#: headless backends in order of preference, with the shared libraries MuJoCo's bindings load for each
BACKENDS = (("egl", ("libEGL.so.1", "libEGL.so")), ("osmesa", ("libOSMesa.so.8", "libOSMesa.so.6", "libOSMesa.so")))
#: where libglvnd looks for EGL vendor drivers: its libEGL loads without one, and then no display initialises
EGL_VENDOR_DIRS = ("/usr/share/glvnd/egl_vendor.d", "/etc/glvnd/egl_vendor.d")
#: MUJOCO_GL values that render without a display, and those that switch MuJoCo's rendering off
HEADLESS = ("egl", "osmesa")
DISABLED = ("disable", "disabled", "off", "false", "0")


class RenderingUnavailable(RotorlabError, RuntimeError):
    """No OpenGL backend MuJoCo can render with offscreen in this process."""


def has_display(environ=None) -> bool:
    """Whether a window system is there to render through (always outside Linux)."""
    env = os.environ if environ is None else environ
    return not sys.platform.startswith("linux") or any(env.get(k) for k in ("DISPLAY", "WAYLAND_DISPLAY"))


def _loads(names) -> bool:
    for name in names:
        try:
            ctypes.CDLL(name)
        except OSError:
            continue
        return True
    return False


def _egl_vendor_present() -> bool:
    """A libglvnd EGL vendor driver is installed (or the environment names one); True where libglvnd's vendor
    folders do not exist at all (a libEGL that is the driver itself)."""
    if os.environ.get("__EGL_VENDOR_LIBRARY_FILENAMES") or os.environ.get("__EGL_VENDOR_LIBRARY_DIRS"):
        return True
    dirs = [Path(d) for d in EGL_VENDOR_DIRS if Path(d).is_dir()]
    return not dirs or any(any(d.glob("*.json")) for d in dirs)


def choose() -> str | None:
    """The headless ``MUJOCO_GL`` value this machine supports: 'egl', else 'osmesa', else None.

    Examples
    --------
    >>> from rotorlab import glbackend
    >>> glbackend.choose() in ("egl", "osmesa", None)
    True
    """
    for name, libs in BACKENDS:
        if _loads(libs) and (name != "egl" or _egl_vendor_present()):
            return name
    return None


def select() -> str | None:
    """Set ``MUJOCO_GL`` to :func:`choose`'s backend where nothing else decides it: Linux, no display, the
    variable unset, MuJoCo not imported yet. Returns the value set (None: left alone); ``import rotorlab``
    calls it."""
    if "MUJOCO_GL" in os.environ or "mujoco" in sys.modules or has_display():
        return None
    chosen = choose()
    if chosen is not None:
        os.environ["MUJOCO_GL"] = chosen
    return chosen


def render_modes() -> list[str]:
    """The render modes the environments declare here: ``['rgb_array']`` where MuJoCo has a backend to render
    with (a display, or MUJOCO_GL set to a headless one), else none.

    Examples
    --------
    >>> import rotorlab
    >>> from rotorlab import glbackend
    >>> glbackend.render_modes() in (["rgb_array"], [])
    True
    """
    gl = os.environ.get("MUJOCO_GL", "").lower().strip()
    if gl in DISABLED:
        return []
    return ["rgb_array"] if gl in HEADLESS or has_display() else []


#: why there is no backend, and what to do
_NONE = ("no OpenGL backend to render with: there is no display (DISPLAY / WAYLAND_DISPLAY) and neither EGL (libEGL "
         "with a vendor driver, e.g. Debian/Ubuntu libegl1 libegl-mesa0) nor OSMesa (libosmesa6) is installed")
_HINT = ("install one, or set MUJOCO_GL=egl or osmesa before Python starts; everything but render() works without "
         "it (render_mode=None)")


def require() -> None:
    """Raise :class:`RenderingUnavailable`, saying what to install, where :func:`render_modes` is empty."""
    if not render_modes():
        gl = os.environ.get("MUJOCO_GL", "")
        why = f"MUJOCO_GL={gl} switches MuJoCo's rendering off" if gl.lower().strip() in DISABLED else _NONE
        raise RenderingUnavailable(f"{why}; {_HINT}")


def renderer(model, height: int, width: int):
    """A ``mujoco.Renderer`` of ``model`` (``height`` x ``width`` pixels) on the process's backend.

    Raises
    ------
    RenderingUnavailable
        Where no backend works, saying what to install.
    """
    import mujoco

    require()
    try:
        return mujoco.Renderer(model, height, width)
    except Exception as exc:  # MuJoCo's FatalError, PyOpenGL's and the backend's own errors alike
        gl = os.environ.get("MUJOCO_GL") or "glfw (MUJOCO_GL unset)"
        raise RenderingUnavailable(f"MuJoCo could not open an OpenGL context with MUJOCO_GL={gl}: {exc}; "
                                   f"{_HINT}") from exc
