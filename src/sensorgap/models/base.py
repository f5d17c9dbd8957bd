"""The interface every sensor type implements, and the pieces they share.

A sensor type is a ``SensorModel`` subclass with a pydantic ``Params`` schema. For one
scene (mount, target, conditions) ``prepare`` folds every constant term into dB once and
returns a ``PreparedSensor`` whose ``snr_db(r, az, el)`` is a pure numpy function of the
geometry. Register new types with ``sensorgap.models.registry.register``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel

from sensorgap.config.target import TargetConfig
from sensorgap.models.conditions import Band, Conditions
from sensorgap.models.geometry import Mount, pattern_loss_db, separation_cos

if TYPE_CHECKING:
    from sensorgap.models.camera import CameraParams
    from sensorgap.models.lidar import LidarParams

F64 = NDArray[np.float64]
SnrFunction = Callable[[F64, F64, F64], F64]
GlareSnrFunction = Callable[[F64, F64, F64, F64], F64]


@dataclass
class PreparedSensor:
    """A sensor ready to evaluate in one scene.

    Attributes:
        snr_db: SNR (dB) of in-view points from range (m), azimuth and elevation (rad) in
            the sensor frame. Never called with r <= 0.
        terms_db: the constant terms folded into ``snr_db`` (for audit reports), dB.
        effects: which effects were modelled for this scene (e.g. ``glare``), with a note.
        uses_angles: whether ``snr_db`` reads azimuth/elevation (a gain pattern); when not,
            callers may pass zeros and skip computing them.
        snr_db_glare: for sensors the sun can blind: SNR (dB) with a per-point glare
            factor ``g`` in [0, 1]: the sensor's glare weight for the sun direction
            (``SensorModel.glare_weights``) times the falloff with the angle between the
            sun and the line of sight to the point (``SensorModel.glare_falloff``; see
            ``glare_factors``), ``snr_db_glare(r, az, el, g)``; ``None`` when the scene has
            no direct sun or the sensor is immune. For a scene prepared with a sun
            direction and ``g`` from it, it equals ``snr_db``.
        signal_db, snr_from_signal: the same split in two, for lookup maps of glare-prone
            sensors: the received signal (dB, a smooth function of the geometry that can be
            tabulated) and SNR (dB) from that signal, a glare factor and the range (m);
            ``snr_db_glare(r, az, el, g) == snr_from_signal(signal_db(r, az, el), g, r)``.
        veil_constants: the constants of the built-in camera's ``snr_from_signal`` (ln of
            the veil-to-object radiance ratio at ``theta_min``, ln of the thermal noise in
            electrons, the one-way weather loss in dB/m, ``theta_min`` in deg, sigma in dBsm,
            the IFOV in dB, the pixel count in dB, ln of the veil's contrast noise, the
            summation pixel count in dB) for the
            compiled glare lookup (``coverage.fastglare``); ``None``: the lookup calls
            ``snr_from_signal``.
        signal_constants: the constants of the built-in camera's ``signal_db`` (k in dB,
            sigma in dBsm, the IFOV in dB, the pixel count in dB, the one-way weather loss
            in dB/m, the field-of-view edge loss in dB, hfov and vfov in rad), so the
            compiled glare lookup evaluates points at the edge of the view exactly
            (``coverage.fastglare.camera_signal_db``); ``None``: it leaves them to numpy.
    """

    snr_db: SnrFunction
    uses_angles: bool = True
    snr_db_glare: GlareSnrFunction | None = None
    signal_db: SnrFunction | None = None
    snr_from_signal: Callable[[F64, F64, F64], F64] | None = None
    veil_constants: tuple[float, ...] | None = None
    signal_constants: tuple[float, ...] | None = None
    terms_db: dict[str, float] = field(default_factory=dict)
    effects: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class RangeLosses:
    """The range-dependent losses the built-in sensors share: the weather loss along the
    path and the gain loss over the field of view (``pattern_loss_db``). Each sensor's own
    range law (R^-4, R^-2 beam fill, pixel count) stays in its module.

    Attributes:
        weather_db_m: weather loss per metre of range, dB/m (the one-way specific
            attenuation times the passes through the weather: 2 for the active sensors,
            1 for a camera).
        edge_loss_db: one-way gain loss at the field-of-view edge, dB (0: none).
        hfov, vfov: the mount's field of view, rad.
        edge_passes: how often the pattern loss applies (2: transmit and receive antenna).
    """

    weather_db_m: float
    edge_loss_db: float
    hfov: float
    vfov: float
    edge_passes: float = 1.0

    @classmethod
    def of(
        cls,
        one_way_db_km: float,
        weather_passes: float,
        mount: Mount,
        edge_loss_db: float,
        edge_passes: float = 1.0,
    ) -> RangeLosses:
        """The losses of a sensor at ``mount`` in weather of one-way specific attenuation
        ``one_way_db_km`` (dB/km) crossed ``weather_passes`` times, with ``edge_loss_db``
        (dB) at the edge of the view applied ``edge_passes`` times."""
        return cls(
            weather_passes * one_way_db_km / 1000.0,
            edge_loss_db,
            mount.hfov,
            mount.vfov,
            edge_passes,
        )

    @property
    def uses_angles(self) -> bool:
        """Whether the losses depend on azimuth and elevation (an edge loss)."""
        return self.edge_loss_db > 0.0

    def apply(self, level_db: F64 | float, spreading_db: F64, r: F64, az: F64, el: F64) -> F64:
        """``level_db - spreading_db - weather_db_m r`` less the pattern loss, dB, at
        range ``r`` (m), azimuth ``az`` and elevation ``el`` (rad, sensor frame)."""
        out = level_db - spreading_db - self.weather_db_m * r
        if self.edge_loss_db > 0.0:
            out = out - self.edge_passes * pattern_loss_db(
                az, el, self.hfov, self.vfov, self.edge_loss_db
            )
        return out


class SensorModel(ABC):
    """Base class of the phenomenological sensor models (Ponn et al. 2019, eq. 1-10)."""

    #: Name used in vehicle files (``devices.<name>.type``).
    type_name: ClassVar[str]
    #: Pydantic schema of the physical parameters.
    Params: ClassVar[type[BaseModel]]

    def __init__(self, params: BaseModel) -> None:
        self.params = params

    @abstractmethod
    def band(self) -> Band:
        """The band this sensor works in (selects the weather attenuation)."""

    @abstractmethod
    def prepare(self, mount: Mount, target: TargetConfig, conditions: Conditions) -> PreparedSensor:
        """Fold every scene constant into a ``PreparedSensor``."""

    def may_be_glared(self, mount: Mount, conditions: Conditions) -> bool:
        """Whether the direct sun can affect this sensor in ``conditions`` (default: no)."""
        return False

    def glare_weights(self, mount: Mount, sun_directions: F64) -> F64:
        """Glare weight in [0, 1] for (N, 3) vehicle-frame sun unit vectors (rows of NaN:
        no direct sun); default: immune (zeros)."""
        return np.zeros(len(sun_directions))

    def glare_falloff(self, cos_sep: F64) -> F64:
        """Glare relative to its largest value, in [0, 1], for the cosine of the angle
        between the sun and the line of sight to a point; default: no falloff (ones)."""
        return np.ones(np.shape(cos_sep))

    def glare_cone(self, mount: Mount) -> GlareCone | None:
        """The glare weight as a ``GlareCone`` (compiled lookups use it), or ``None`` when
        the sensor is immune or its weight has another form (then ``glare_weights`` is
        called)."""
        return None


class OpticalSensor(SensorModel):
    """A sensor of the optical band (camera, lidar): its weather attenuation is the optical
    band's at the parameters' ``wavelength_m``."""

    params: CameraParams | LidarParams

    def band(self) -> Band:
        """Optical band at the sensor's (centre or laser) wavelength."""
        return Band("optical", wavelength_m=self.params.wavelength_m)


@dataclass(frozen=True)
class GlareCone:
    """A glare weight of the standard form: 1 for sun directions inside the field of
    view, ``cos^2(pi/2 * a / margin)`` at an angle ``a`` (rad) outside it (0 where that
    falls to 1e-9 or below), 0 from ``margin`` on.

    Attributes:
        rotation: 3x3 sensor axes (columns) in the vehicle frame.
        half_h, half_v: half the horizontal / vertical field of view, rad.
        margin: rad (0: no fade).
        yaw, pitch: the mount's, rad (``rotation`` = Rz(yaw) Ry(pitch)).
    """

    rotation: NDArray[np.float64]
    half_h: float
    half_v: float
    margin: float
    yaw: float = 0.0
    pitch: float = 0.0


def glare_factors(
    model: SensorModel,
    mount: Mount,
    dx: F64,
    dy: F64,
    dz: F64 | float,
    sun_directions: F64,
    weights: F64 | None = None,
) -> F64:
    """Per-point glare factor ``g`` of ``PreparedSensor.snr_db_glare``: the glare weight of
    each point's sun direction ((N, 3), vehicle frame, NaN rows: none; or the given
    ``weights``) times the falloff with the angle between that sun and the line of sight
    from the mount to the point (offsets ``dx``, ``dy``, ``dz`` from the mount, m)."""
    w = model.glare_weights(mount, sun_directions) if weights is None else weights
    g = np.zeros(len(w))
    on = np.flatnonzero(w > 0.0)
    if on.size:
        dz_a = np.broadcast_to(np.asarray(dz, dtype=np.float64), np.shape(dx))
        c = separation_cos(dx[on], dy[on], dz_a[on], sun_directions[on])
        g[on] = w[on] * model.glare_falloff(c)
    return g
