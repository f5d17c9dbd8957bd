"""Vehicle files: body, sensor devices (physical parameters) and sensor mounts.

Frame: OpenSCENARIO / ISO 8855 vehicle frame: x forward, y left, z up, origin at the
centre of the rear axle on the ground. Yaw counter-clockwise from x; pitch by the
right-hand rule about y, so a positive pitch tilts the boresight *down*. Degrees in files.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import ConfigDict, Field, field_validator, model_validator

from sensorgap.config.common import Name, Strict

#: Upper limit of a mount's range, m (docs/limits.md).
MAX_RANGE_M = 10_000.0
#: At most this many sensors (mounts) and devices per vehicle (docs/limits.md).
MAX_SENSORS = 128
#: A sensor is mounted on the body: its position may lie at most this far outside the body
#: box, m (estimate: side mirrors stick out 0.1-0.25 m, roof sensor pods up to about
#: 0.4 m; System A's mirror cameras are 0.075 m outside its 1.95 m width). Farther out is
#: almost always a position measured from another origin (front axle, body centre).
MOUNT_TOLERANCE_M = 0.5


def _xyz(v: list[float]) -> str:
    return "(" + ", ".join(f"{c:g}" for c in v) + ")"


#: Largest false-alarm probability of a ROC (a detector declaring a target in one cell of
#: ten without one is no detector; near 1 scipy's Marcum Q overflowed).
MAX_PFA = 0.1


#: Shortest blind zone a mount may have, m, when it has one (an estimate: ultrasonic
#: blind zones are decimetres; a 5e-324 m one made shapely's union divide by zero in the
#: near field, RuntimeWarnings on stderr: hostile round 44).
MIN_BLIND_RANGE_M = 0.001
#: Narrowest smoothstep transition, dB (an estimate: a sensor's detection rises over dB,
#: not 1e-307 dB; one of 1e-307 dB overflowed in its division, hostile round 44).
MIN_HALF_WIDTH_DB = 0.01


class RocConfig(Strict):
    """How SNR becomes a detection probability (see ``sensorgap.models.roc``).

    ``paper`` (default): 50 % at ``snr50_db`` (Ponn 2019 after Hasch 2012: 10 dB in sunny
    conditions) on a Swerling-1-shaped curve ``Pd = 0.5^((1 + SNR50) / (1 + SNR))`` that
    approaches 1 asymptotically, and 0 below ``floor_db`` (no detection declared below it).
    ``smoothstep``: 0 below ``snr50_db - half_width_db``, exactly 1 above
    ``snr50_db + half_width_db``, cubic in dB between. ``swerling0`` / ``swerling1``: exact
    single-pulse detection of a steady / Rayleigh-fluctuating target at false-alarm
    probability ``pfa``.
    ``albersheim``: Albersheim's approximation, only inside its validity range.
    ``pfa`` is 1e-15..0.1 (``MAX_PFA``; radar practice is 1e-4..1e-8).
    """

    kind: Literal["paper", "smoothstep", "swerling0", "swerling1", "albersheim"] = "paper"
    snr50_db: float = Field(default=10.0, ge=-50.0, le=100.0)
    floor_db: float = Field(default=0.0, ge=-300.0, le=100.0)
    #: at least ``MIN_HALF_WIDTH_DB`` (an estimate: narrower is a step, and 1e-307 dB
    #: overflowed the smoothstep's division; hostile round 44)
    half_width_db: float = Field(default=6.0, ge=MIN_HALF_WIDTH_DB, le=50.0)
    #: at most ``MAX_PFA``: a pfa near 1 (1 - 1e-15) overflowed scipy's Marcum Q (tgamma)
    pfa: float = Field(default=1.0e-6, ge=1.0e-15, le=MAX_PFA)
    n_pulses: int = Field(default=1, ge=1, le=8096)

    @model_validator(mode="after")
    def _albersheim_range(self) -> RocConfig:
        if self.kind == "albersheim" and not (1e-7 <= self.pfa <= 1e-3):
            raise ValueError(f"albersheim is valid for 1e-7 <= pfa <= 1e-3 only, got {self.pfa:g}")
        return self


class DeviceConfig(Strict):
    """A sensor device: its type and physical parameters (equations 1-10 of the paper).

    The parameters depend on ``type`` and are validated by the sensor type's own schema
    (``sensorgap.models.registry``). ``sources`` names the data sheet, paper or standard of
    every parameter, or says ``estimate: ...``.
    """

    model_config = ConfigDict(extra="allow", frozen=True, allow_inf_nan=False, strict=True)

    type: str
    sources: dict[str, str] = Field(default_factory=dict)
    roc: RocConfig | None = None

    def params(self) -> dict[str, Any]:
        """The physical parameters (everything but type, sources, roc)."""
        return dict(self.model_extra or {})


class MountConfig(Strict):
    """One mounted sensor: which device, where, which way, what it can see."""

    id: str = Field(pattern=r"^[A-Za-z0-9_\-]+$", max_length=64)
    device: str
    position_m: list[float] = Field(
        min_length=3, max_length=3, description="x, y, z in the vehicle frame, m"
    )
    yaw_deg: float = Field(default=0.0, ge=-360.0, le=360.0)
    pitch_deg: float = Field(default=0.0, ge=-90.0, le=90.0)
    # > 0: a sensor without a field of view sees nothing (refused rather than evaluated)
    hfov_deg: float = Field(gt=0.0, le=360.0)
    vfov_deg: float = Field(gt=0.0, le=180.0)
    min_range_m: float = Field(default=0.0, ge=0.0, le=MAX_RANGE_M)
    max_range_m: float = Field(
        ge=0.01,
        le=MAX_RANGE_M,
        description="Detection range limit, m (at most 10 km)",
    )
    source: str = Field(description="Where pose, field of view and range come from")

    @field_validator("position_m")
    @classmethod
    def _finite_position(cls, v: list[float]) -> list[float]:
        if not all(math.isfinite(c) and abs(c) <= 100.0 for c in v):
            raise ValueError("position must be three finite numbers within +-100 m")
        if len(v) == 3 and v[2] < 0.0:  # the frame's origin is on the ground
            raise ValueError(f"z must be >= 0 m (on or above the road), got {v[2]:g}")
        return v

    @model_validator(mode="after")
    def _ranges(self) -> MountConfig:
        if 0.0 < self.min_range_m < MIN_BLIND_RANGE_M:
            raise ValueError(
                f"min_range_m must be 0 (no blind zone) or at least {MIN_BLIND_RANGE_M:g} m, "
                f"got {self.min_range_m!r}"
            )
        if self.min_range_m >= self.max_range_m:
            raise ValueError(
                f"min_range_m ({self.min_range_m}) must be below max_range_m ({self.max_range_m})"
            )
        return self

    @property
    def yaw_rad(self) -> float:
        """Yaw, rad, wrapped to (-pi, pi]."""
        y = math.remainder(math.radians(self.yaw_deg), 2.0 * math.pi)
        return math.pi if y == -math.pi else y

    @property
    def pitch_rad(self) -> float:
        """Pitch (positive = down), rad."""
        return math.radians(self.pitch_deg)

    @property
    def hfov_rad(self) -> float:
        """Horizontal field of view (full angle), rad."""
        return math.radians(self.hfov_deg)

    @property
    def vfov_rad(self) -> float:
        """Vertical field of view (full angle), rad."""
        return math.radians(self.vfov_deg)


class BodyConfig(Strict):
    """The vehicle body: name, size, footprint relative to the rear axle."""

    name: Name
    description: str = ""
    length_m: float = Field(gt=0.5, le=30.0)
    width_m: float = Field(gt=0.5, le=5.0)
    height_m: float = Field(gt=0.5, le=6.0)
    wheelbase_m: float = Field(gt=0.5, le=20.0)
    rear_overhang_m: float = Field(gt=0.0, le=10.0)  # (the schema said >= 0; hostile round 45)
    max_speed_m_s: float = Field(default=70.0, ge=0.1, le=150.0)
    sources: dict[str, str] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _axles_inside(self) -> BodyConfig:
        # the frame's origin is the rear axle: both axles lie inside the body, so the rear
        # bumper is behind it (x_rear < 0) and the front bumper ahead of the front axle
        # (a 0.6 m car with a 1.13 m overhang put the front bumper behind the origin)
        if not 0.0 < self.rear_overhang_m < self.length_m:
            raise ValueError(
                f"rear_overhang_m must be > 0 and below length_m ({self.length_m:g}), "
                f"got {self.rear_overhang_m:g}"
            )
        if not self.wheelbase_m < self.length_m - self.rear_overhang_m:
            raise ValueError(
                f"wheelbase_m must be below length_m - rear_overhang_m "
                f"({self.length_m - self.rear_overhang_m:g}), got {self.wheelbase_m:g}"
            )
        return self

    @property
    def x_rear_m(self) -> float:
        """x of the rear bumper in the vehicle frame, m."""
        return -self.rear_overhang_m

    @property
    def x_front_m(self) -> float:
        """x of the front bumper in the vehicle frame, m."""
        return self.length_m - self.rear_overhang_m

    def outside_by(self, x: float, y: float, z: float) -> float:
        """How far a vehicle-frame point (m) lies outside the body box (0 inside), m."""
        dx = max(self.x_rear_m - x, x - self.x_front_m, 0.0)
        dy = max(abs(y) - 0.5 * self.width_m, 0.0)
        dz = max(z - self.height_m, 0.0)  # z >= 0 is checked with the position
        return math.sqrt(dx * dx + dy * dy + dz * dz)

    def footprint(self) -> list[tuple[float, float]]:
        """Footprint rectangle corners (x, y) in the vehicle frame, m, counter-clockwise."""
        xr, xf, hw = self.x_rear_m, self.x_front_m, 0.5 * self.width_m
        return [(xr, -hw), (xf, -hw), (xf, hw), (xr, hw)]


class VehicleConfig(Strict):
    """A whole vehicle file."""

    #: the file format's version: an integer, 1 (``Literal[1]`` took ``true`` and ``1.0``
    #: as 1 even in strict mode: hostile round eighteen, F1)
    schema_version: int = Field(default=1, ge=1, le=1, strict=True)
    vehicle: BodyConfig
    reaction: str = Field(
        default="ads_default",
        min_length=1,
        max_length=200,
        description="Reaction model of the vehicle under test: a preset of "
        "templates/reactions.toml or a path to a TOML file with one",
    )
    roc: RocConfig = Field(default_factory=RocConfig)
    devices: dict[str, DeviceConfig] = Field(max_length=MAX_SENSORS)
    sensors: list[MountConfig] = Field(min_length=1, max_length=MAX_SENSORS)

    @model_validator(mode="after")
    def _consistent(self) -> VehicleConfig:
        seen: set[str] = set()
        for i, s in enumerate(self.sensors):
            if s.id in seen:
                raise ValueError(f"sensors[{i}].id: duplicate sensor id {s.id!r}")
            seen.add(s.id)
            if s.device not in self.devices:
                raise ValueError(
                    f"sensors[{i}].device: unknown device {s.device!r}; "
                    f"defined: {', '.join(sorted(self.devices)) or 'none'}"
                )
            off = self.vehicle.outside_by(*s.position_m)
            if off > MOUNT_TOLERANCE_M + 1e-9:  # (at the tolerance itself: accepted)
                raise ValueError(
                    f"sensors[{i}].position_m: {s.id!r} at {_xyz(s.position_m)} m lies "
                    f"{off:.2f} m outside the body (x {self.vehicle.x_rear_m:g}.."
                    f"{self.vehicle.x_front_m:g}, |y| <= {0.5 * self.vehicle.width_m:g}, "
                    f"z <= {self.vehicle.height_m:g} m); allowed: within "
                    f"{MOUNT_TOLERANCE_M:g} m of it (positions are from the rear-axle "
                    "centre on the ground, x forward, y left)"
                )
        return self
