"""An environment resolved for evaluation: attenuation per band, light, sun direction.

Attenuation is computed once per (environment, band) from the documented formulas in
``sensorgap.models.attenuation`` and cached; a scene only computes the bands it uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from sensorgap.config.environment import EnvironmentConfig
from sensorgap.models import attenuation as att

BandKind = Literal["radio", "optical", "acoustic"]


@dataclass(frozen=True)
class Band:
    """The part of the spectrum a sensor works in.

    Attributes:
        kind: ``radio`` (radar), ``optical`` (lidar, camera) or ``acoustic`` (ultrasonic).
        frequency_hz: carrier frequency, Hz (radio, acoustic).
        wavelength_m: wavelength, m (optical).
    """

    kind: BandKind
    frequency_hz: float = 0.0
    wavelength_m: float = 0.0


#: The reference wavelength of meteorological visibility, 550 nm (WMO No. 8, 2018, vol. I
#: ch. 9: the luminous flux of an incandescent lamp at 2700 K, peak eye sensitivity).
VISIBLE_BAND = Band("optical", wavelength_m=550e-9)


@dataclass
class Conditions:
    """An environment preset resolved for one ego heading.

    Attributes:
        env: the preset.
        sun_direction: unit vector to the sun in the vehicle frame, or ``None`` when no
            direct sun can reach a sensor (not visible, or at/below the horizon).
    """

    env: EnvironmentConfig
    sun_direction: tuple[float, float, float] | None
    _cache: dict[Band, float] = field(default_factory=dict, repr=False)

    @classmethod
    def from_config(cls, env: EnvironmentConfig, ego_heading_rad: float = 0.0) -> Conditions:
        """Resolve ``env`` for an ego heading (rad, counter-clockwise from world x = east,
        OpenDRIVE convention); only matters for a sun given in the ``world`` frame."""
        sun = env.sun
        direction = None
        if sun is not None and sun.visible and sun.elevation_deg > 0.0:
            if sun.frame == "vehicle":
                az = sun.azimuth_rad
            else:  # OpenSCENARIO: clockwise from north -> ENU counter-clockwise from east
                az = 0.5 * math.pi - sun.azimuth_rad - ego_heading_rad
            el = sun.elevation_rad
            direction = (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el))
        return cls(env=env, sun_direction=direction)

    @staticmethod
    def sun_directions(
        env: EnvironmentConfig, ego_heading_rad: NDArray[np.float64]
    ) -> NDArray[np.float64] | None:
        """Vehicle-frame unit vectors to the sun, (N, 3), one per ego heading (rad), the
        vectorised ``from_config(...).sun_direction``; ``None`` when the sun cannot reach
        any sensor (no sun, not visible, at or below the horizon)."""
        sun = env.sun
        if sun is None or not sun.visible or sun.elevation_deg <= 0.0:
            return None
        h = np.asarray(ego_heading_rad, dtype=np.float64)
        if sun.frame == "vehicle":
            az = np.full(h.shape, sun.azimuth_rad)
        else:
            az = 0.5 * math.pi - sun.azimuth_rad - h
        el = sun.elevation_rad
        return np.column_stack(
            [math.cos(el) * np.cos(az), math.cos(el) * np.sin(az), np.full(h.shape, math.sin(el))]
        )

    @property
    def roc_shift_db(self) -> float:
        """SNR penalty of the ROC in this weather, dB."""
        return self.env.roc_shift_db

    def fog_lwc_g_m3(self) -> float:
        """Fog liquid water content, g/m3: given, or from visibility (Kunkel 1984) in fog."""
        if self.env.fog_lwc_g_m3 is not None:
            return self.env.fog_lwc_g_m3
        if self.env.visibility_m >= att.FOG_VISIBILITY_LIMIT_M:
            return 0.0
        return att.fog_lwc_from_visibility_g_m3(self.env.visibility_m)

    def meteorological_visibility_m(self) -> float:
        """Meteorological optical range of this weather, m: Koschmieder's law at 2 %
        contrast, ``V = 3.912 / beta``, with ``beta`` the total optical extinction (fog or
        haze from ``visibility_m``, plus rain and snow) at 550 nm, the wavelength of the
        definition (WMO No. 8, 2018, vol. I ch. 9). Equals ``visibility_m`` without rain
        and snow; rounded to 0.1 m (so 50 m fog gives exactly 50.0, not 49.999...)."""
        gamma = self.attenuation_db_km(VISIBLE_BAND)  # dB/km, one way
        beta_per_m = gamma * math.log(10.0) / 10.0 / 1000.0
        if beta_per_m <= 0.0:
            return math.inf
        return round(att.KOSCHMIEDER_2PCT / beta_per_m, 1)

    def attenuation_db_km(self, band: Band) -> float:
        """One-way specific attenuation for ``band`` in this environment, dB/km."""
        if band not in self._cache:
            self._cache[band] = self._compute(band)
        return self._cache[band]

    def _compute(self, band: Band) -> float:
        e = self.env
        if band.kind == "acoustic":
            # Ponn 2019 after Sonbul & Kalashnikov 2014: 1000 dB/km, weather-independent.
            return att.ULTRASONIC_DB_KM
        if band.kind == "radio":
            f = band.frequency_hz
            total = att.gaseous_db_km(f, e.pressure_hpa, e.temperature_c, e.water_vapour_g_m3)
            if e.rain_mm_h > 0.0:
                total += att.rain_radar_db_km(f, e.rain_mm_h)
            lwc = self.fog_lwc_g_m3()
            if lwc > 0.0:
                total += att.fog_radar_db_km(f, lwc, e.temperature_c)
            if e.snow_mm_h > 0.0:
                total += att.snow_radar_db_km(f, e.snow_mm_h, e.snow_wet)
            return total
        lam = band.wavelength_m
        total = att.optical_fog_db_km(lam, e.visibility_m)
        if e.rain_mm_h > 0.0:
            total += att.optical_rain_db_km(e.rain_mm_h)
        if e.snow_mm_h > 0.0:
            total += att.optical_snow_db_km(lam, e.snow_mm_h, e.snow_wet)
        return total
