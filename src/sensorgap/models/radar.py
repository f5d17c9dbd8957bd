"""Radar (Ponn 2019, eq. 1-3): radar equation with receiver thermal noise.

``T_sys = T0 (F - 1) + T_ant`` from the noise figure F (IEEE Std 145 / Skolnik); the noise
bandwidth approximates ``1 / tau`` (Ludloff 1998, p. 42).
"""

from __future__ import annotations

from pydantic import Field

from sensorgap.config.common import Strict
from sensorgap.models.conditions import Conditions
from sensorgap.models.constants import SPEED_OF_LIGHT_M_S, T0_K
from sensorgap.models.radar_equation import RadarEquationSensor
from sensorgap.models.registry import register


class RadarParams(Strict):
    """Physical parameters of a radar device (eq. 2-3)."""

    frequency_hz: float = Field(ge=1.0e9, le=3.0e11, description="Carrier frequency, Hz")
    tx_power_dbm: float = Field(ge=-30.0, le=60.0, description="Transmit power P_e, dBm")
    tx_gain_dbi: float = Field(ge=-20.0, le=60.0, description="Boresight gain G_e, dBi")
    rx_gain_dbi: float = Field(ge=-20.0, le=60.0, description="Boresight gain G_r, dBi")
    noise_bandwidth_hz: float = Field(ge=1.0, le=1.0e12, description="B_n ~ 1/tau, Hz")
    noise_figure_db: float = Field(ge=0.0, le=40.0, description="Receiver noise figure F, dB")
    antenna_temperature_k: float = Field(default=290.0, ge=1.0, le=1.0e4, description="K")
    system_loss_db: float = Field(
        default=0.0, ge=0.0, le=100.0, description="Fixed two-way losses (fascia, cables), dB"
    )
    fov_edge_loss_db: float = Field(
        default=3.0, ge=0.0, le=60.0, description="One-way antenna gain loss at the FOV edge, dB"
    )

    @property
    def system_noise_temperature_k(self) -> float:
        """T_sys = T0 (F - 1) + T_ant, K."""
        return T0_K * (10.0 ** (self.noise_figure_db / 10.0) - 1.0) + self.antenna_temperature_k


@register
class Radar(RadarEquationSensor):
    """Automotive radar, eq. 2-3 of Ponn et al. 2019, in the radio band."""

    type_name = "radar"
    Params = RadarParams
    params: RadarParams
    band_kind = "radio"

    def wavelength_m(self, conditions: Conditions) -> float:
        """``c / f``, m."""
        return SPEED_OF_LIGHT_M_S / self.params.frequency_hz
