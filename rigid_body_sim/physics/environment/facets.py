"""A box-and-panels facet model and the two torques it feels in orbit: solar radiation
pressure and aerodynamic drag (no ROS; plain numpy, the reference for the compiled loops'
``facets_kernel``).

Each facet is flat and one-sided: area A (m²), outward unit normal n̂ and centre of
pressure r_cp relative to the centre of mass (both in body axes), specular and diffuse
reflectivities ρ_s, ρ_d (absorbed: 1 − ρ_s − ρ_d) and a drag coefficient C_D. A facet
whose normal faces away from the Sun or from the flow feels nothing (no self-shadowing
between facets: the usual box-and-panels approximation).

* SRP, ŝ the unit vector to the Sun, cos θ = n̂·ŝ > 0, P the pressure (N/m²):
  F = −P A cos θ [(1 − ρ_s) ŝ + (2 ρ_s cos θ + (2/3) ρ_d) n̂]  (Vallado §8.6.4;
  Wertz, *Spacecraft Attitude Determination and Control*, §17.2).
* Drag, v the velocity relative to the atmosphere, v̂ = v/|v|, ρ the density:
  F = −½ ρ C_D A max(0, n̂·v̂) |v|² v̂.
* The torque about the centre of mass is Σ r_cp × F.

Density: :func:`exponential_density`, Vallado's exponential table (Fundamentals of
Astrodynamics, table 8-4, 0 … 1000 km, the last layer extended above), at the height
above the ellipsoid (approximated as r − R_E(1 − f sin² φ), φ the geocentric latitude:
within ~10 m of the geodetic height below 2,000 km).
"""
from dataclasses import dataclass
import math

import numpy as np

SOLAR_PRESSURE = 4.56e-6   # N/m², the solar flux at 1 AU over c (1361 W/m² / c)
FLATTENING = 1.0 / 298.257223563   # WGS-84
EARTH_RADIUS = 6378137.0   # m, WGS-84 equatorial
FACET_SIZE = 10            # area, normal (3), centre (3), specular, diffuse, C_D

# Vallado table 8-4: base height (km), nominal density (kg/m³), scale height (km)
EXPONENTIAL_TABLE = np.array([
    (0, 1.225, 7.249), (25, 3.899e-2, 6.349), (30, 1.774e-2, 6.682),
    (40, 3.972e-3, 7.554), (50, 1.057e-3, 8.382), (60, 3.206e-4, 7.714),
    (70, 8.770e-5, 6.549), (80, 1.905e-5, 5.799), (90, 3.396e-6, 5.382),
    (100, 5.297e-7, 5.877), (110, 9.661e-8, 7.263), (120, 2.438e-8, 9.473),
    (130, 8.484e-9, 12.636), (140, 3.845e-9, 16.149), (150, 2.070e-9, 22.523),
    (180, 5.464e-10, 29.740), (200, 2.789e-10, 37.105), (250, 7.248e-11, 45.546),
    (300, 2.418e-11, 53.628), (350, 9.518e-12, 53.298), (400, 3.725e-12, 58.515),
    (450, 1.585e-12, 60.828), (500, 6.967e-13, 63.822), (600, 1.454e-13, 71.835),
    (700, 3.614e-14, 88.667), (800, 1.170e-14, 124.64), (900, 5.245e-15, 181.05),
    (1000, 3.019e-15, 268.00)]) * np.array([1e3, 1.0, 1e3])   # → m, kg/m³, m


def height(position) -> float:
    """Height above the ellipsoid (m), to first order in the flattening."""
    r = np.asarray(position, float)
    rn = float(np.linalg.norm(r))
    sin_lat = r[2] / rn
    return rn - EARTH_RADIUS * (1.0 - FLATTENING * sin_lat * sin_lat)


def exponential_density(h: float) -> float:
    """ρ (kg/m³) at height h (m): the layer's ρ0·exp(−(h − h0)/H); 0 below the surface
    is not reached (an orbit's perigee is checked at load)."""
    i = max(0, int(np.searchsorted(EXPONENTIAL_TABLE[:, 0], h, side='right')) - 1)
    h0, rho0, scale = EXPONENTIAL_TABLE[i]
    return float(rho0 * math.exp(-(h - h0) / scale))


@dataclass(frozen=True, eq=False)
class FacetModel:
    """The facets (n of them), body axes: areas (n,), normals (n, 3) unit, centres (n, 3)
    m from the centre of mass, specular (n,), diffuse (n,), drag_coefficient (n,)."""
    areas: np.ndarray
    normals: np.ndarray
    centres: np.ndarray
    specular: np.ndarray
    diffuse: np.ndarray
    drag_coefficient: np.ndarray

    @classmethod
    def build(cls, areas, normals, centres, specular=0.0, diffuse=0.0,
              drag_coefficient=2.2, prefix='facets'):
        """From flat lists (normals and centres 3 per facet; the coefficients one value or
        one per facet); normals are normalised. ValueError naming ``prefix.key``."""
        a = np.asarray(areas, float).reshape(-1)
        n = len(a)
        if n == 0:
            raise ValueError(f'{prefix}.areas: no facet (give one area per facet, m^2)')
        if not np.all(np.isfinite(a)) or np.any(a <= 0.0):
            raise ValueError(f'{prefix}.areas: every area must be finite and > 0, got '
                             f'{a.tolist()}')
        vectors = {}
        for key, values in (('normals', normals), ('centres', centres)):
            v = np.asarray(values, float).reshape(-1)
            if v.size != 3 * n:
                raise ValueError(f'{prefix}.{key}: needs 3 values per facet ({3 * n} for '
                                 f'{n} facets), got {v.size}')
            if not np.all(np.isfinite(v)):
                raise ValueError(f'{prefix}.{key}: not finite: {v.tolist()}')
            vectors[key] = v.reshape(n, 3)
        norms = np.linalg.norm(vectors['normals'], axis=1)
        if np.any(norms < 1e-9):
            raise ValueError(f'{prefix}.normals: facet {int(np.argmin(norms))} has a zero '
                             'normal')
        coefficients = {}
        for key, values in (('specular', specular), ('diffuse', diffuse),
                            ('drag_coefficient', drag_coefficient)):
            c = np.asarray(values, float).reshape(-1)
            if c.size == 1:
                c = np.full(n, c[0])
            if c.size != n:
                raise ValueError(f'{prefix}.{key}: needs one value or one per facet ({n}), '
                                 f'got {c.size}')
            if not np.all(np.isfinite(c)) or np.any(c < 0.0):
                raise ValueError(f'{prefix}.{key}: must be finite and >= 0, got '
                                 f'{c.tolist()}')
            coefficients[key] = c
        total = coefficients['specular'] + coefficients['diffuse']
        if np.any(total > 1.0):
            raise ValueError(f'{prefix}.specular + {prefix}.diffuse: at most 1 per facet '
                             f'(the rest is absorbed), got {total.tolist()}')
        return cls(a, vectors['normals'] / norms[:, None], vectors['centres'], **coefficients)

    def __len__(self):
        return len(self.areas)

    def packed(self, to_frame=None) -> np.ndarray:
        """(n·FACET_SIZE,) for the loops' element array; ``to_frame`` maps body-axes
        vectors (…, 3) to the loops' frame (the principal frame)."""
        normals, centres = self.normals, self.centres
        if to_frame is not None:
            normals, centres = to_frame(normals), to_frame(centres)
        return np.column_stack([self.areas, normals, centres, self.specular, self.diffuse,
                                self.drag_coefficient]).reshape(-1)

    def srp(self, sun, pressure):
        """(force N, torque N·m), body axes, for the unit vector ``sun`` to the Sun (body
        axes) and the pressure (N/m², 0 in the shadow)."""
        s = np.asarray(sun, float)
        cos = self.normals @ s
        lit = cos > 0.0
        c = np.where(lit, cos, 0.0)
        f = -pressure * (self.areas * c)[:, None] * (
            (1.0 - self.specular)[:, None] * s
            + (2.0 * self.specular * c + (2.0 / 3.0) * self.diffuse)[:, None] * self.normals)
        return f.sum(axis=0), np.cross(self.centres, f).sum(axis=0)

    def drag(self, velocity, density):
        """(force N, torque N·m), body axes, for the velocity relative to the atmosphere
        (m/s, body axes) and the density (kg/m³)."""
        v = np.asarray(velocity, float)
        speed = float(np.linalg.norm(v))
        if speed == 0.0:
            return np.zeros(3), np.zeros(3)
        u = v / speed
        c = np.maximum(self.normals @ u, 0.0)
        f = -0.5 * density * speed ** 2 * (self.drag_coefficient * self.areas * c)[:, None] \
            * u
        return f.sum(axis=0), np.cross(self.centres, f).sum(axis=0)
