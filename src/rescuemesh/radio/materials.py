"""What one wall of a given material costs a 2.4 GHz link, from the material's electrical properties.

Owns: the ITU-R P.2040-3 material table (Table 3), each wall material's nominal thickness and the
transmission loss of such a slab at normal incidence. Must not know maps, grids, the medium.

Theory (ITU-R P.2040-3, 2.1.4 and 3.2; Born and Wolf for the slab): a material's complex relative
permittivity at f GHz is eta = a f^b - j 17.98 c f^d / f. A homogeneous slab of thickness t at
normal incidence transmits

    T = (1 - G^2) e^(-j q) / (1 - G^2 e^(-2 j q)),   G = (1 - sqrt(eta)) / (1 + sqrt(eta)),
    q = 2 pi t sqrt(eta) / lambda,

with the reflections inside the slab summed; the wall's loss is -20 log10 |T| dB. At 2.44 GHz:
plasterboard stud wall (two 12.5 mm boards) 2.2 dB, brick 0.12 m 3.4 dB, concrete 0.20 m 14.8 dB,
glass 6 mm 1.9 dB, wood 40 mm 0.6 dB (`wall_loss_db`; tests/radio/test_materials.py). They fall in
the ranges measured at 2.4 GHz (plasterboard 1-3 dB, brick 3-8, concrete 8-15: COST 231 Final
Report 4.7; Wilson, "Electromagnetic wave propagation through building materials", NIST 1997).
Limitations: normal incidence only (an oblique path crosses more material), a wall is one
homogeneous slab (no studs, no reinforcement bars, no air gap between boards: two boards are
priced as twice one).
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

from rescuemesh.maps.model import WallMaterial

#: Speed of light in m/s.
C_M_S = 299_792_458.0


@dataclass(frozen=True, slots=True)
class MaterialProperties:
    """ITU-R P.2040-3 Table 3: eta' = a f^b, sigma = c f^d S/m (f in GHz), valid f_min..f_max GHz."""

    a: float
    b: float
    c: float
    d: float
    f_min_ghz: float
    f_max_ghz: float

    def permittivity(self, f_ghz: float) -> complex:
        """Complex relative permittivity eta' - j eta'' at f GHz (P.2040-3 eqs. 28, 9b)."""
        real = self.a * f_ghz ** self.b
        sigma = self.c * f_ghz ** self.d
        return complex(real, -17.98 * sigma / f_ghz)


#: ITU-R P.2040-3 (08/2023), Table 3 (the rows this model uses).
P2040_TABLE3: dict[str, MaterialProperties] = {
    "concrete": MaterialProperties(5.24, 0.0, 0.0462, 0.7822, 1.0, 100.0),
    "brick": MaterialProperties(3.91, 0.0, 0.0238, 0.16, 1.0, 40.0),
    "plasterboard": MaterialProperties(2.73, 0.0, 0.0085, 0.9395, 1.0, 100.0),
    "wood": MaterialProperties(1.99, 0.0, 0.0047, 1.0718, 0.001, 100.0),
    "glass": MaterialProperties(6.31, 0.0, 0.0036, 1.3394, 0.1, 100.0),
}

#: Each wall material as P.2040 material, thickness in m and number of such layers (stated
#: assumptions, docs/radio.md): a light partition is two 12.5 mm plasterboards on studs; an
#: interior brick wall half a brick (0.12 m, the Kolakowski flat's walls are 0.10-0.17 m in its
#: layout); a load-bearing (reinforced) concrete wall 0.20 m; glazing 6 mm; furniture and doors 40 mm of wood.
WALL_BUILD: dict[WallMaterial, tuple[str, float, int]] = {
    WallMaterial.LIGHT: ("plasterboard", 0.0125, 2),
    WallMaterial.BRICK: ("brick", 0.12, 1),
    WallMaterial.CONCRETE: ("concrete", 0.20, 1),
    WallMaterial.GLASS: ("glass", 0.006, 1),
    WallMaterial.WOOD: ("wood", 0.04, 1),
}


def slab_loss_db(material: str, thickness_m: float, frequency_mhz: float) -> float:
    """Transmission loss in dB of a slab of P.2040 `material`, `thickness_m` thick, at normal incidence."""
    props = P2040_TABLE3[material]
    f_ghz = frequency_mhz / 1000.0
    if not props.f_min_ghz <= f_ghz <= props.f_max_ghz:
        raise ValueError(f"{material}: P.2040 gives its properties for {props.f_min_ghz:g}-{props.f_max_ghz:g} GHz, "
                         f"not {f_ghz:g} GHz")
    if not thickness_m >= 0.0:
        raise ValueError(f"slab thickness must be >= 0 m, got {thickness_m}")
    n = cmath.sqrt(props.permittivity(f_ghz))  # complex refractive index, Im < 0 (loss)
    gamma = (1 - n) / (1 + n)
    q = 2.0 * math.pi * thickness_m * n * frequency_mhz * 1e6 / C_M_S
    t = (1 - gamma**2) * cmath.exp(-1j * q) / (1 - gamma**2 * cmath.exp(-2j * q))
    return -20.0 * math.log10(abs(t))


def wall_loss_db(material: WallMaterial, frequency_mhz: float) -> float:
    """The loss in dB of one wall of `material` as built in WALL_BUILD, at `frequency_mhz`."""
    name, thickness, layers = WALL_BUILD[material]
    return layers * slab_loss_db(name, thickness, frequency_mhz)
