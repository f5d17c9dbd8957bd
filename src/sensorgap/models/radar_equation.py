"""The radar equation shared by radar and ultrasonic sensors (Ponn 2019, eq. 2-3):

``SNR = P_e G_e G_r sigma lambda^2 / ((4 pi)^3 R^4 L_oa(R) k B_n T_sys)``

in dB, with ``L_oa(R) = L_sys + 2 gamma R`` (two-way atmospheric/weather loss at one-way
specific attenuation gamma, plus fixed system losses such as a bumper fascia) and the
antenna gains reduced over the field of view by ``pattern_loss_db`` (each antenna once).
"""

from __future__ import annotations

import math
from abc import abstractmethod
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from sensorgap.config.target import TargetConfig
from sensorgap.models.base import F64, PreparedSensor, RangeLosses, SensorModel
from sensorgap.models.conditions import Band, BandKind, Conditions
from sensorgap.models.constants import BOLTZMANN_J_K
from sensorgap.models.geometry import Mount

if TYPE_CHECKING:
    from sensorgap.models.radar import RadarParams
    from sensorgap.models.ultrasonic import UltrasonicParams

FOUR_PI_CUBED_DB = 30.0 * math.log10(4.0 * math.pi)


def radar_constant_db(
    *,
    tx_power_dbm: float,
    tx_gain_dbi: float,
    rx_gain_dbi: float,
    cross_section_m2: float,
    wavelength_m: float,
    system_loss_db: float,
    noise_bandwidth_hz: float,
    system_noise_temperature_k: float,
) -> dict[str, float]:
    """The range-independent terms of eq. 3 in dB (their sum is the SNR at R = 1 m on
    boresight without weather loss)."""
    return {
        "P_e [dBW]": tx_power_dbm - 30.0,
        "G_e [dBi]": tx_gain_dbi,
        "G_r [dBi]": rx_gain_dbi,
        "sigma [dBsm]": 10.0 * math.log10(cross_section_m2),
        "lambda^2 [dB m2]": 20.0 * math.log10(wavelength_m),
        "-(4 pi)^3 [dB]": -FOUR_PI_CUBED_DB,
        "-L_sys [dB]": -system_loss_db,
        "-k B_n T_sys [dBW]": -10.0
        * math.log10(BOLTZMANN_J_K * noise_bandwidth_hz * system_noise_temperature_k),
    }


def prepare_radar_equation(
    terms_db: dict[str, float], one_way_db_km: float, mount: Mount, edge_loss_db: float
) -> PreparedSensor:
    """A ``PreparedSensor`` evaluating eq. 3 with R^-4 spreading, two-way weather loss and
    the pattern loss of both antennas."""
    k_db = math.fsum(terms_db.values())
    losses = RangeLosses.of(one_way_db_km, 2.0, mount, edge_loss_db, edge_passes=2.0)

    def snr_db(r: F64, az: F64, el: F64) -> F64:
        return losses.apply(k_db, 40.0 * np.log10(r), r, az, el)

    terms = dict(terms_db)
    terms["weather one-way [dB/km]"] = one_way_db_km
    return PreparedSensor(snr_db=snr_db, terms_db=terms, uses_angles=losses.uses_angles)


def prepare_radar_device(
    p: RadarParams | UltrasonicParams,
    wavelength_m: float,
    cross_section_m2: float,
    one_way_db_km: float,
    mount: Mount,
) -> PreparedSensor:
    """A radar-equation device (radar or ultrasonic) in one scene: its constant terms
    (``radar_constant_db``) with the carrier ``wavelength_m`` (m) and the target's
    ``cross_section_m2`` (m2), the one-way weather attenuation ``one_way_db_km`` (dB/km)
    and the gain loss over the field of view of ``mount``."""
    terms = radar_constant_db(
        tx_power_dbm=p.tx_power_dbm,
        tx_gain_dbi=p.tx_gain_dbi,
        rx_gain_dbi=p.rx_gain_dbi,
        cross_section_m2=cross_section_m2,
        wavelength_m=wavelength_m,
        system_loss_db=p.system_loss_db,
        noise_bandwidth_hz=p.noise_bandwidth_hz,
        system_noise_temperature_k=p.system_noise_temperature_k,
    )
    return prepare_radar_equation(terms, one_way_db_km, mount, p.fov_edge_loss_db)


class RadarEquationSensor(SensorModel):
    """A sensor of the radar equation (radar, ultrasonic): eq. 2-3 with the target's
    ``rcs_m2`` and the wavelength of its carrier (``wavelength_m``), in the band of kind
    ``band_kind`` at the carrier frequency."""

    #: The band's kind (``radio``, ``acoustic``): selects the weather attenuation.
    band_kind: ClassVar[BandKind]
    params: RadarParams | UltrasonicParams

    def band(self) -> Band:
        """The ``band_kind`` band at the carrier frequency (``frequency_hz``)."""
        return Band(self.band_kind, frequency_hz=self.params.frequency_hz)

    @abstractmethod
    def wavelength_m(self, conditions: Conditions) -> float:
        """The carrier's wavelength in ``conditions``, m."""

    def prepare(self, mount: Mount, target: TargetConfig, conditions: Conditions) -> PreparedSensor:
        """Radar equation with the carrier wavelength and the target's radar cross-section
        (``rcs_m2``)."""
        return prepare_radar_device(
            self.params,
            self.wavelength_m(conditions),
            target.rcs_m2,
            conditions.attenuation_db_km(self.band()),
            mount,
        )
