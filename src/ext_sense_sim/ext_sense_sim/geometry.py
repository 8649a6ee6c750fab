"""Materials (handbook values) and cross-sections of the held objects, and where they are held."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ext_sense_sim.errors import SceneError


@dataclass(frozen=True)
class Material:
    """Linear elastic material: modulus, Pa; density, kg/m^3; loss factor (dimensionless)."""

    youngs_pa: float
    density: float
    loss_factor: float


MATERIALS: dict[str, Material] = {
    "acrylic": Material(3.2e9, 1190.0, 0.04),
    "steel": Material(200e9, 7850.0, 0.002),
    "abs": Material(2.2e9, 1050.0, 0.03),
    "porcelain": Material(70e9, 2400.0, 0.003),
    "cardboard": Material(1.5e9, 700.0, 0.06),
}


@dataclass(frozen=True)
class Geometry:
    """The held object as a straight prismatic beam held at one end (SI units).

    ``held_length_m`` runs from the held end to the pads' edge; the second moments are for
    bending toward (normal) and along (tangent) the pads; ``width_m`` is across the pads.
    """

    kind: str
    material: Material
    length_m: float
    held_length_m: float
    area_m2: float
    inertia_normal_m4: float
    inertia_tangent_m4: float
    width_m: float

    @property
    def free_length_m(self) -> float:
        """Length of the free span beyond the grasp, metres."""
        return self.length_m - self.held_length_m


def section_properties(section: Mapping[str, Any]) -> tuple[float, float, float, float]:
    """Area, inertia toward and along the pads and contact width of a section.

    ``section``: ``{shape: circle, diameter_m}``, ``{shape: rect, width_m, thickness_m}``
    (thickness toward the pads) or ``{shape: hollow_rect, width_m, thickness_m, wall_m}``.
    """
    shape = section.get("shape")

    def dim(key: str) -> float:
        try:
            value = float(section[key])
        except (KeyError, TypeError, ValueError) as err:
            raise SceneError(
                f"Section '{shape}' needs a positive number '{key}'. Got {section.get(key)!r}."
            ) from err
        if not value > 0:
            raise SceneError(f"Section '{shape}': '{key}' must be > 0. Got {value!r} instead.")
        return value

    if shape == "circle":
        d = dim("diameter_m")
        area = math.pi * d**2 / 4
        inertia = math.pi * d**4 / 64
        return area, inertia, inertia, d
    if shape == "rect":
        w, t = dim("width_m"), dim("thickness_m")
        return w * t, w * t**3 / 12, t * w**3 / 12, w
    if shape == "hollow_rect":
        w, t, c = dim("width_m"), dim("thickness_m"), dim("wall_m")
        if 2 * c >= min(w, t):
            raise SceneError(f"Section 'hollow_rect': 'wall_m' ({c}) must be < half of w and t.")
        wi, ti = w - 2 * c, t - 2 * c
        return (w * t - wi * ti, (w * t**3 - wi * ti**3) / 12, (t * w**3 - ti * wi**3) / 12, w)
    raise SceneError(
        f"Section 'shape' must be one of ['circle', 'rect', 'hollow_rect']. Got {shape!r} instead."
    )


def geometry_from(obj: Mapping[str, Any], held_length_m: float) -> Geometry:
    """Build the :class:`Geometry` of a scene's ``object`` section."""
    material_name = obj.get("material", "acrylic")
    if material_name not in MATERIALS:
        raise SceneError(
            f"Object 'material' must be one of {sorted(MATERIALS)}. Got {material_name!r} instead."
        )
    try:
        length = float(obj["length_m"])
    except (KeyError, TypeError, ValueError) as err:
        raise SceneError(
            f"Object 'length_m' must be a number. Got {obj.get('length_m')!r}."
        ) from err
    if not 0 < held_length_m < length:
        raise SceneError(
            f"Grasp 'held_length_m' must be in (0, length_m={length}). Got {held_length_m!r}."
        )
    area, i_n, i_t, width = section_properties(obj.get("section", {}))
    return Geometry(
        kind=str(obj.get("kind", "rod")),
        material=MATERIALS[material_name],
        length_m=length,
        held_length_m=float(held_length_m),
        area_m2=area,
        inertia_normal_m4=i_n,
        inertia_tangent_m4=i_t,
        width_m=width,
    )
