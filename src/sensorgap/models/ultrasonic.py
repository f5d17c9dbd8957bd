"""Ultrasonic sensor (Ponn 2019, eq. 1-3): the radar equation with the acoustic wavelength
``lambda = c_sound / f`` (Sonbul & Kalashnikov 2014) and the paper's constant 1000 dB/km
air attenuation, weather-independent. ``system_noise_temperature_k`` is the equivalent
noise temperature of the paper's ``k B_n T_sys`` noise term (an acoustic receiver has no
thermal-noise temperature of its own: an estimate by construction).
"""

from __future__ import annotations

from pydantic import Field

from sensorgap.config.common import Strict
from sensorgap.models.conditions import Conditions
from sensorgap.models.constants import speed_of_sound_m_s
from sensorgap.models.radar_equation import RadarEquationSensor
from sensorgap.models.registry import register


class UltrasonicParams(Strict):
    """Physical parameters of an ultrasonic transducer (eq. 2-3)."""

    frequency_hz: float = Field(ge=1.0e3, le=1.0e6, description="Carrier frequency, Hz")
    tx_power_dbm: float = Field(ge=-60.0, le=60.0, description="Acoustic power P_e, dBm")
    tx_gain_dbi: float = Field(ge=-20.0, le=60.0, description="Directivity G_e, dBi")
    rx_gain_dbi: float = Field(ge=-20.0, le=60.0, description="Directivity G_r, dBi")
    noise_bandwidth_hz: float = Field(ge=1.0, le=1.0e9, description="B_n ~ 1/tau, Hz")
    system_noise_temperature_k: float = Field(ge=1.0, le=1.0e12, description="Equivalent T_sys, K")
    system_loss_db: float = Field(default=0.0, ge=0.0, le=100.0, description="dB")
    fov_edge_loss_db: float = Field(
        default=3.0, ge=0.0, le=60.0, description="One-way directivity loss at the FOV edge, dB"
    )


@register
class Ultrasonic(RadarEquationSensor):
    """Ultrasonic park-distance sensor, eq. 2-3 of Ponn et al. 2019, in the acoustic band
    (attenuation: the paper's constant 1000 dB/km)."""

    type_name = "ultrasonic"
    Params = UltrasonicParams
    params: UltrasonicParams
    band_kind = "acoustic"

    def wavelength_m(self, conditions: Conditions) -> float:
        """The acoustic wavelength ``c_sound / f`` at the ambient temperature, m."""
        return speed_of_sound_m_s(conditions.env.temperature_c) / self.params.frequency_hz
