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


#: Range of an environment's ROC shift ``roc_shift_db``, dB (docs/limits.md). An estimate:
#: the paper shifts its ROC curves by unpublished amounts in adverse weather; the presets use
#: 1-3 dB. +30 dB: beyond it the shift alone blinds every preset sensor (the camera/lidar
#: curves' zero at 10 - 12 + 30 = 28 dB SNR, the radar floor at 7.5 + 30 = 37.5 dB); the
#: weather's attenuation is computed apart, the shift is a penalty on top. -10 dB: a shift
#: may make a curve better than the paper's sunny reference, at most so far that its 50 %
#: point (10 dB) stays at 0 dB SNR or above (no more detection than noise; -100 gave a
#: radar Pd of 1.0 at -7.6 dB SNR).
MIN_ROC_SHIFT_DB = -10.0
MAX_ROC_SHIFT_DB = 30.0


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
        ge=MIN_ROC_SHIFT_DB,
        le=MAX_ROC_SHIFT_DB,
        description="SNR penalty of the ROC in this weather (paper: curves shifted), dB "
        "(range: an estimate, docs/limits.md)",
    )
    sun: SunConfig | None = None
    sources: dict[str, str] = Field(default_factory=dict)
