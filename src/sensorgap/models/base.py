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
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel

from sensorgap.config.target import TargetConfig
from sensorgap.models.conditions import Band, Conditions
from sensorgap.models.geometry import Mount

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
        snr_db_glare: for sensors the sun can blind: SNR (dB) with a per-point glare weight
            ``w`` in [0, 1] (the fraction of the direct-sun term applied, see
            ``SensorModel.glare_weights``), ``snr_db_glare(r, az, el, w)``; ``None`` when the
            scene has no direct sun or the sensor is immune. With ``w`` equal to the
            scene's own weight it equals ``snr_db``.
        signal_db, snr_from_signal: the same split in two, for lookup maps of glare-prone
            sensors: the received signal (dB, a smooth function of the geometry that can be
            tabulated) and SNR (dB) from that signal and a glare weight;
            ``snr_db_glare(r, az, el, w) == snr_from_signal(signal_db(r, az, el), w)``.
    """

    snr_db: SnrFunction
    uses_angles: bool = True
    snr_db_glare: GlareSnrFunction | None = None
    signal_db: SnrFunction | None = None
    snr_from_signal: Callable[[F64, F64], F64] | None = None
    terms_db: dict[str, float] = field(default_factory=dict)
    effects: dict[str, str] = field(default_factory=dict)


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
    def prepare(
        self, mount: Mount, target: TargetConfig, conditions: Conditions
    ) -> PreparedSensor:
        """Fold every scene constant into a ``PreparedSensor``."""

    def may_be_glared(self, mount: Mount, conditions: Conditions) -> bool:
        """Whether the direct sun can affect this sensor in ``conditions`` (default: no)."""
        return False

    def glare_weights(self, mount: Mount, sun_directions: F64) -> F64:
        """Glare weight in [0, 1] for (N, 3) vehicle-frame sun unit vectors (rows of NaN:
        no direct sun); default: immune (zeros)."""
        return np.zeros(len(sun_directions))

    def glare_cone(self, mount: Mount) -> GlareCone | None:
        """The glare weight as a ``GlareCone`` (compiled lookups use it), or ``None`` when
        the sensor is immune or its weight has another form (then ``glare_weights`` is
        called)."""
        return None


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

