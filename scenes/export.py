"""MJCF files of the twins: the scene a simulator builds, written as XML that MuJoCo loads on its own.

``python -m mujoco.viewer --mjcf FILE.xml`` opens it. MuJoCo's own writer (``MjSpec.to_xml``) prints every number
with six significant digits (``%g``), which is not the model the simulator runs and, for the hingeless hubs'
flat discs (principal inertias with ``A + B = C`` exactly), not even a loadable one: rounding breaks MuJoCo's
triangle-inequality check. So the XML is MuJoCo's, and the numbers of every named element, the inertials, the
options and the keyframes are rewritten here from the spec at full precision (``repr``: the shortest text that
reads back as the same double). MuJoCo has no public option for the precision of its writer, hence this layer.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from rotorlab import atomic
from rotorlab.scenes import build_scene

#: XML tag -> (how the spec finds the element by name, attributes written from the spec at full precision)
_NAMED = {
    "body": ("body", ("pos", "quat")),
    "geom": ("geom", ("pos", "quat", "size", "fluidcoef", "friction", "margin", "gap")),
    "site": ("site", ("pos", "quat", "size")),
    "joint": ("joint", ("pos", "axis", "range", "stiffness", "damping", "armature", "springref", "frictionloss")),
    "general": ("actuator", ("gear", "gainprm", "biasprm", "dynprm", "ctrlrange", "forcerange", "actrange",
                             "lengthrange", "delay")),
    "spatial": ("tendon", ("range", "stiffness", "damping", "springlength")),
    "key": ("key", ("qpos", "qvel", "act", "ctrl", "mpos", "mquat", "time")),
}
_QUAT = mujoco.mjtOrientation.mjORIENTATION_QUAT
_OPTION = ("timestep", "gravity", "wind", "magnetic", "density", "viscosity")


def _num(values) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(values))


def _refine(elem: ET.Element, obj, attrs, placed=None) -> None:
    """Rewrite ``attrs`` of ``elem`` from the spec object ``obj``. ``placed``: the element's position and
    orientation in its parent body as compiled (``(pos, quat)``), for elements whose spec orientation is not a
    quaternion (Euler angles, axis-angle: MuJoCo's writer converts those to a quaternion itself)."""
    for a in attrs:
        if a not in elem.attrib or not hasattr(obj, a):
            continue
        value = getattr(obj, a)
        if a == "quat" and getattr(getattr(obj, "alt", None), "type", None) not in (None, _QUAT):
            if placed is None:
                continue  # under a <frame>: the writer's own (rounded) quaternion stays
            value = placed[1]
        # whole arrays: MuJoCo's writer drops trailing entries equal to the element's defaults, which are not
        # always the spec's (a site's unused size entries are 0 in the spec, 0.005 by default in the XML)
        elem.set(a, _num(value))


def mjcf(scene) -> str:
    """The MJCF text of a compiled :class:`rotorlab.scenes.Scene` at full precision.

    Parameters
    ----------
    scene : rotorlab.scenes.Scene
        From :func:`rotorlab.scenes.build_scene` (its ``spec`` is written).

    Returns
    -------
    str
        MJCF that ``mujoco.MjModel.from_xml_string`` compiles to ``scene.model`` (tests/test_export_mjcf.py
        compares every array of the two models and a 1 s run from the ``hover`` keyframe).

    Examples
    --------
    >>> import mujoco
    >>> from rotorlab.scenes import build_scene
    >>> from rotorlab.scenes.export import mjcf
    >>> scene = build_scene("pitch-rig", "anteos-p2a2")
    >>> model = mujoco.MjModel.from_xml_string(mjcf(scene))
    >>> bool((model.body_inertia == scene.model.body_inertia).all())
    True
    """
    spec, model = scene.spec, scene.model
    root = ET.fromstring(spec.to_xml())
    parent = {child: p for p in root.iter() for child in p}
    compiled = {"body": (model.body, "pos", "quat"), "geom": (model.geom, "pos", "quat"),
                "site": (model.site, "pos", "quat")}
    for tag, (kind, attrs) in _NAMED.items():
        find = getattr(spec, kind)
        for elem in root.iter(tag):
            name = elem.get("name")
            obj = find(name) if name else None
            if obj is None:
                continue
            if tag == "site":
                elem.set("size", "")  # left out at its default, whose unused entries differ from the spec's
            placed = None
            if tag in compiled and parent[elem].tag != "frame":
                view = compiled[tag][0](name)
                placed = (view.pos, view.quat)
            _refine(elem, obj, attrs, placed)
    for body in root.iter("body"):
        inertial = body.find("inertial")
        b = spec.body(body.get("name")) if body.get("name") else None
        if inertial is not None and b is not None:
            for a, field in (("mass", "mass"), ("pos", "ipos"), ("quat", "iquat"), ("diaginertia", "inertia"),
                             ("fullinertia", "fullinertia")):
                if a in inertial.attrib:
                    inertial.set(a, _num(getattr(b, field)))
    for option in root.iter("option"):
        _refine(option, spec.option, _OPTION)
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


def export(vehicle, scene: str, path) -> mujoco.MjModel:
    """Build ``scene`` with ``vehicle`` (name, TOML path or VehicleSpec), write its MJCF atomically to ``path``
    and return the model the simulator would run (for checks)."""
    s = build_scene(scene, vehicle)
    atomic.write_text(path, mjcf(s))
    return s.model


__all__ = ["mjcf", "export"]
