"""Lidar (Ponn 2019, eq. 4-5).

Received power (eq. 4, small-angle beam of divergence Theta):
``P_r = P_e sigma_eff A_r / (pi^2 R^4 Theta^2 L_oa(R))``, noise (eq. 5):
``P_n = 2 h nu B_n + k B_n T_sys`` (shot + thermal/background).

Extended targets (docs/models.md, physics.md pitfall 4): eq. 4 is the point-target law and
holds only while the target is smaller than the beam footprint. A diffuse (Lambertian)
target of reflectance rho that fills the beam returns ``P_r = P_e rho A_r / (pi R^2)``,
which eq. 4 reproduces with ``sigma_eff = rho pi R^2 Theta^2``. We therefore use
``sigma_eff = min(sigma, rho pi R^2 Theta^2)`` (``target_law = "min"``, default);
``target_law = "point"`` keeps the paper's eq. 4 unchanged.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from sensorgap.config.common import Strict
from sensorgap.config.target import TargetConfig
from sensorgap.models.base import F64, OpticalSensor, PreparedSensor, RangeLosses
from sensorgap.models.conditions import Conditions
from sensorgap.models.constants import BOLTZMANN_J_K, PLANCK_J_S, SPEED_OF_LIGHT_M_S
from sensorgap.models.geometry import Mount
from sensorgap.models.registry import register


class LidarParams(Strict):
    """Physical parameters of a pulsed direct-detection lidar (eq. 4-5)."""

    wavelength_m: float = Field(ge=2.0e-7, le=1.2e-5, description="Laser wavelength, m")
    peak_power_w: float = Field(ge=1.0e-6, le=1.0e5, description="Peak emitted power P_e, W")
    beam_divergence_rad: float = Field(ge=1.0e-6, le=0.2, description="Theta, rad")
    receiver_diameter_m: float = Field(ge=1.0e-4, le=1.0, description="Aperture diameter, m")
    noise_bandwidth_hz: float = Field(ge=1.0, le=1.0e12, description="B_n ~ 1/tau, Hz")
    system_noise_temperature_k: float = Field(ge=1.0, le=1.0e7, description="T_sys, K")
    system_loss_db: float = Field(
        default=0.0, ge=0.0, le=100.0, description="Fixed losses (optics transmission), dB"
    )
    fov_edge_loss_db: float = Field(
        default=0.0, ge=0.0, le=60.0, description="Sensitivity loss at the FOV edge, dB"
    )
    target_law: Literal["min", "point"] = "min"


@register
class Lidar(OpticalSensor):
    """Pulsed time-of-flight lidar, eq. 4-5 of Ponn et al. 2019."""

    type_name = "lidar"
    Params = LidarParams
    params: LidarParams

    def prepare(self, mount: Mount, target: TargetConfig, conditions: Conditions) -> PreparedSensor:
        """Fold eq. 4-5 constants; the range law switches at the beam-fill range."""
        p = self.params
        nu = SPEED_OF_LIGHT_M_S / p.wavelength_m
        noise_w = (
            2.0 * PLANCK_J_S * nu * p.noise_bandwidth_hz
            + BOLTZMANN_J_K * p.noise_bandwidth_hz * p.system_noise_temperature_k
        )
        area = math.pi * p.receiver_diameter_m**2 / 4.0
        terms = {
            "P_e [dBW]": 10.0 * math.log10(p.peak_power_w),
            "A_r [dB m2]": 10.0 * math.log10(area),
            "-pi^2 [dB]": -20.0 * math.log10(math.pi),
            "-Theta^2 [dB]": -20.0 * math.log10(p.beam_divergence_rad),
            "-L_sys [dB]": -p.system_loss_db,
            "-P_n [dBW]": -10.0 * math.log10(noise_w),
        }
        k_db = math.fsum(terms.values())
        sigma_db = 10.0 * math.log10(target.rcs_m2)
        fill_db = 10.0 * math.log10(target.lidar_reflectance * math.pi * p.beam_divergence_rad**2)
        extended = p.target_law == "min"
        gamma = conditions.attenuation_db_km(self.band())
        losses = RangeLosses.of(gamma, 2.0, mount, p.fov_edge_loss_db)

        def snr_db(r: F64, az: F64, el: F64) -> F64:
            lr = np.log10(r)
            sig = np.minimum(sigma_db, fill_db + 20.0 * lr) if extended else sigma_db
            return np.asarray(losses.apply(k_db + sig, 40.0 * lr, r, az, el), dtype=np.float64)

        terms["sigma [dBsm]"] = sigma_db
        terms["rho pi Theta^2 [dB]"] = fill_db
        terms["weather one-way [dB/km]"] = gamma
        return PreparedSensor(snr_db=snr_db, terms_db=terms, uses_angles=losses.uses_angles)
