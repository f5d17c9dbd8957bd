"""Target classes (pedestrian, bike, car, truck): cross-sections, size, reference height."""

from __future__ import annotations

from pydantic import Field, model_validator

from sensorgap.config.common import PresetName, Strict

#: A box's size, m (docs/limits.md): a target class's and an occluder's
#: (``coverage.occluders.Occluder``): the smallest side, the longest length, width and
#: height.
MIN_SIZE_M = 0.01
MAX_LENGTH_M = 50.0
MAX_WIDTH_M = 10.0
MAX_HEIGHT_M = 10.0


class TargetConfig(Strict):
    """One target class.

    Cross-sections after Ponn et al. 2019, Sec. III: ``rcs_m2`` for the active sensors
    (radar, lidar, ultrasonic: 1, 10, 100, 200 m2) and the geometric
    ``camera_cross_section_m2`` for cameras (0.9, 1.35, 2.7, 6.75 m2).
    """

    name: PresetName
    description: str = ""
    rcs_m2: float = Field(
        ge=1.0e-6,
        le=1.0e4,
        description="Cross-section for active sensors, m2 (paper Sec. III)",
    )
    camera_cross_section_m2: float = Field(
        ge=1.0e-6, le=1.0e3, description="Geometric cross-section, m2 (paper)"
    )
    length_m: float = Field(ge=MIN_SIZE_M, le=MAX_LENGTH_M)
    width_m: float = Field(ge=MIN_SIZE_M, le=MAX_WIDTH_M)
    height_m: float = Field(ge=MIN_SIZE_M, le=MAX_HEIGHT_M)
    reference_height_m: float = Field(
        ge=0.0,
        le=10.0,
        description="Height at which coverage is evaluated for this class, m",
    )
    lidar_reflectance: float = Field(
        ge=1.0e-6, le=1.0, description="Diffuse reflectance at the lidar wavelength (extended law)"
    )
    camera_reflectance: float = Field(
        ge=1.0e-6, le=1.0, description="Diffuse reflectance in the camera band (rho/pi term)"
    )
    max_speed_m_s: float = Field(
        default=70.0,
        ge=0.1,
        le=150.0,
        description="Upper bound for trajectories, m/s",
    )
    sources: dict[str, str] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _reference_on_body(self) -> TargetConfig:
        if self.reference_height_m > self.height_m:
            raise ValueError(
                f"reference_height_m ({self.reference_height_m:g} m) must not "
                f"exceed height_m ({self.height_m:g} m): coverage is evaluated "
                "at a height on the target's body"
            )
        return self
