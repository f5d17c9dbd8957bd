"""Environment presets: weather, sun position and lighting, ROC shift."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field

from sensorgap.config.common import PresetName, Strict


class SunConfig(Strict):
    """The sun as seen from the scene.

    ``frame = "vehicle"``: azimuth counter-clockwise from the vehicle's x axis (ISO 8855,
    positive to the left), as for a coverage map. ``frame = "world"``: OpenSCENARIO
    convention, azimuth clockwise from north (0 = north, 90 = east); converted with the ego
    heading at evaluation time.
    """

    azimuth_deg: float = Field(ge=-360.0, le=360.0)
    elevation_deg: float = Field(ge=-90.0, le=90.0)
    frame: Literal["vehicle", "world"] = "vehicle"
    visible: bool = Field(
        default=True, description="Sun disc visible (clear sky); False under overcast/fog"
    )
    direct_irradiance_w_m2: float = Field(
        default=480.0,
        ge=0.0,
        le=1.0e4,
        description="Direct-normal irradiance in the camera band, W/m2 (for glare, eq. 10)",
    )

    @property
    def azimuth_rad(self) -> float:
        """Azimuth in rad (convention of ``frame``)."""
        return math.radians(self.azimuth_deg)

    @property
    def elevation_rad(self) -> float:
        """Elevation above the horizon in rad."""
        return math.radians(self.elevation_deg)


class EnvironmentConfig(Strict):
    """One environment preset: weather, light, sun."""

    name: PresetName
    description: str = ""
    rain_mm_h: float = Field(default=0.0, ge=0.0, le=500.0)
    snow_mm_h: float = Field(default=0.0, ge=0.0, le=100.0)
    snow_wet: bool = False
    visibility_m: float = Field(
        default=23000.0,
        ge=1.0,
        le=1.0e6,
        description="Meteorological optical range, m (23 km = standard clear air)",
    )
    fog_lwc_g_m3: float | None = Field(
        default=None,
        ge=0.0,
        le=5.0,
        description="Fog liquid water content, g/m3; default derived from visibility (Kunkel 1984)",
    )
    temperature_c: float = Field(default=15.0, ge=-60.0, le=60.0)
    relative_humidity_pct: float = Field(default=50.0, ge=0.0, le=100.0)
    pressure_hpa: float = Field(
        default=1013.25,
        ge=500.0,
        le=1100.0,
        description="Total barometric pressure (roads: ~500-1100), hPa",
    )
    water_vapour_g_m3: float = Field(default=7.5, ge=0.0, le=50.0)
    irradiance_w_m2: float = Field(
        default=534.0,
        ge=0.0,
        le=1.0e4,
        description="Irradiance on objects in the camera band (E_sun of eq. 6), W/m2",
    )
    roc_shift_db: float = Field(
        default=0.0,
        ge=-100.0,
        le=100.0,
        description="SNR penalty of the ROC in this weather (paper: curves shifted), dB",
    )
    sun: SunConfig | None = None
    sources: dict[str, str] = Field(default_factory=dict)
