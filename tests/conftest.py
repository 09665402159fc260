import os

# Rendering tests run headless; MuJoCo picks EGL, falling back to OSMesa in the tests that render.
os.environ.setdefault("MUJOCO_GL", "egl")
