import os

# Rendering tests run headless; MuJoCo picks EGL, falling back to OSMesa in the tests that render.
os.environ.setdefault("MUJOCO_GL", "egl")
# pytest -n 2 already uses both cores: BLAS threads on top of that only fight each other
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
