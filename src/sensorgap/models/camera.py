"""Camera (Ponn 2019, eq. 6-10, after Lange 2000).

Signal electrons (eq. 6-7), with the object's pixel count for an equidistant (f-theta)
lens, ``IFOV = HFOV / N_h`` and ``N_pix,o(R) = min(sigma_cam / (R IFOV)^2, N_pix)``:

``P_r = (rho / pi) E_sun sigma_cam D^2 N_pix,o(R) / (16 R^2 L_oa(R) N_pix)``, with the
object's diffuse reflectance rho: the object returns the radiance ``rho E_sun / pi``
(physics.md pitfall 5; eq. 6 as printed assumes ``rho / pi = 1``), and
``L_oa(R) = L_sys + gamma R`` (one pass object -> camera; the illumination of the object is
``E_sun`` of the environment),
``N_e = P_r t_int QE / (h nu)``.

Noise (eq. 8) ``N_n = sqrt(N_e) + k B_n T_sys t_int QE / (h nu)``; SNR (eq. 9)
``N_e / (N_n + N_e,sun)``.

Direct sun (eq. 10, physics.md pitfall 5). Eq. 10 puts the sun's whole flux through the
aperture (~1e12 electrons) on every pixel; a camera that looks 20 deg away from a low sun
still sees. The sun's effect on the *target's* image is the veiling glare that lens and
windscreen scatter from the sun's image, falling with the angle ``theta`` between the sun and
the line of sight to the target (Stiles-Holladay, CIE 146:2002 disability glare):
``L_veil = k E_dir / theta^2`` (theta in deg, ``k`` = ``veiling_glare_k``, held at its
``veiling_glare_min_deg`` value below that angle). In the units of ``N_e`` the veil over the
object's image is the object's signal before the weather times the veil-to-object radiance
ratio ``V(theta) = L_veil / (rho E_sun / pi)``:

``N_veil = w V(theta) N_e 10^(gamma R / 10)``

with ``w`` the share of the lens the sun reaches: 1 while the sun is inside the field of
view, falling as ``cos^2`` to 0 at ``glare_margin_deg`` outside it (lens hood and housing;
estimate), 0 beyond, at night and under overcast skies.

The veil is a background luminance on the object's pixels and around them, not a copy of
the object: it costs the object contrast, and a larger image averages its fluctuations out.
Two noise terms (eq. 9's form, electrons counted as noise):

* shot noise: ``sqrt(N_e + N_veil n_c / N_pix,o)`` in place of ``sqrt(N_e)`` (eq. 8), with
  ``n_c = max(N_pix,o, 1)`` the pixels the object's light falls on;
* contrast noise: ``c_v N_veil (n_c / N_pix,o) / sqrt(n_s)``, the veil's pixel-to-pixel
  fluctuation ``c_v`` (``veil_contrast_noise``: flare structure, pixel response
  non-uniformity, tone mapping; estimate) averaged over ``n_s = min(n_c, n_sum)`` pixels
  (``veil_summation_px``: spatial summation ends at a critical area; estimate).

With glare the SNR cannot exceed ``sqrt(n_s) / (c_v w V(theta))``: a car filling thousands of
pixels stays visible under a veil as bright as itself, a distant one a few degrees from the
sun does not. Aperture ``D = f / N`` with focal length ``f = pixel_pitch / IFOV``.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from sensorgap.config.common import Strict
from sensorgap.config.target import TargetConfig
from sensorgap.models.base import F64, GlareCone, OpticalSensor, PreparedSensor, RangeLosses
from sensorgap.models.conditions import Conditions
from sensorgap.models.constants import BOLTZMANN_J_K, PLANCK_J_S, SPEED_OF_LIGHT_M_S
from sensorgap.models.geometry import Mount, angle_outside_fov, angles_outside_fov
from sensorgap.models.numerics import LN10_OVER_10
from sensorgap.models.registry import register

_MIN_IFOV_RAD = 1.0e-9  # a zero-width camera still gets a finite pixel angle


class CameraParams(Strict):
    """Physical parameters of a camera (eq. 6-10)."""

    wavelength_m: float = Field(
        default=550e-9, ge=3.0e-7, le=1.5e-5, description="Centre wavelength for h nu, m"
    )
    pixels_h: int = Field(ge=1, le=100_000, description="Horizontal pixel count")
    pixels_v: int = Field(ge=1, le=100_000, description="Vertical pixel count")
    pixel_pitch_m: float = Field(ge=1.0e-7, le=1.0e-4, description="Pixel pitch, m")
    f_number: float = Field(ge=0.5, le=64.0, description="Lens f-number N")
    quantum_efficiency: float = Field(ge=1.0e-6, le=1.0, description="QE")
    integration_time_s: float = Field(ge=1.0e-7, le=1.0, description="t_int, s")
    noise_bandwidth_hz: float = Field(ge=1.0, le=1.0e12, description="B_n, Hz")
    system_noise_temperature_k: float = Field(ge=1.0, le=1.0e7, description="T_sys, K")
    system_loss_db: float = Field(
        default=0.0, ge=0.0, le=100.0, description="Lens/windscreen transmission loss, dB"
    )
    fov_edge_loss_db: float = Field(
        default=3.0, ge=0.0, le=60.0, description="Relative illumination loss at the FOV edge, dB"
    )
    glare_margin_deg: float = Field(
        default=10.0, ge=0.0, le=90.0, description="Sun angle outside the FOV still glaring, deg"
    )
    veiling_glare_k: float = Field(
        default=10.0,
        ge=0.0,
        le=1.0e4,
        description="k of L_veil = k E_glare / theta^2 (theta in deg), (cd/m2)/lx deg2",
    )
    veiling_glare_min_deg: float = Field(
        default=1.0,
        ge=0.1,
        le=30.0,
        description="Sun-target angle below which the veil is held constant, deg "
        "(CIE 146:2002: the glare formula holds from 0.1 deg)",
    )
    veil_contrast_noise: float = Field(
        default=0.25,
        ge=0.0,
        le=10.0,
        description="Pixel-to-pixel fluctuation of the veil relative to its mean (c_v)",
    )
    veil_summation_px: float = Field(
        default=2500.0,
        ge=1.0,
        le=1.0e8,
        description="Pixels over which the veil's fluctuation averages out at most (n_sum)",
    )


@register
class Camera(OpticalSensor):
    """Passive camera, eq. 6-10 of Ponn et al. 2019."""

    type_name = "camera"
    Params = CameraParams
    params: CameraParams

    def glare_weight(self, mount: Mount, conditions: Conditions) -> float:
        """Fraction (0..1) of the direct-sun term of eq. 9-10 applied to this camera."""
        sun = conditions.sun_direction
        if sun is None:
            return 0.0
        outside = angle_outside_fov(mount, sun)
        margin = math.radians(self.params.glare_margin_deg)
        if outside <= 0.0:
            return 1.0
        if outside >= margin:
            return 0.0
        w = math.cos(0.5 * math.pi * outside / margin) ** 2
        return w if w > 1e-9 else 0.0

    def glare_weights(self, mount: Mount, sun_directions: F64) -> F64:
        """Vectorised ``glare_weight`` for (N, 3) vehicle-frame sun unit vectors; rows of
        NaN (no direct sun) get 0."""
        margin = math.radians(self.params.glare_margin_deg)
        outside = angles_outside_fov(mount, sun_directions, limit=margin)
        w = np.where(outside <= 0.0, 1.0, 0.0)
        near = np.flatnonzero((outside > 0.0) & (outside < margin))
        if near.size:
            wn = np.cos(0.5 * math.pi * outside[near] / margin) ** 2
            w[near] = np.where(wn > 1e-9, wn, 0.0)
        return np.asarray(w, dtype=np.float64)

    def glare_cone(self, mount: Mount) -> GlareCone:
        """``glare_weights`` as a ``GlareCone`` (the same weight, for compiled lookups)."""
        return GlareCone(
            np.ascontiguousarray(mount.rotation()),
            0.5 * mount.hfov,
            0.5 * mount.vfov,
            math.radians(self.params.glare_margin_deg),
            mount.yaw,
            mount.pitch,
        )

    def glare_falloff(self, cos_sep: F64) -> F64:
        """Veiling glare relative to its value at ``veiling_glare_min_deg``:
        ``min(1, (theta_min / theta)^2)`` for the cosine of the angle ``theta`` between the
        sun and the line of sight to the target (Stiles-Holladay)."""
        theta = np.degrees(np.arccos(np.clip(cos_sep, -1.0, 1.0)))
        t_min = self.params.veiling_glare_min_deg
        return np.asarray(t_min**2 / np.maximum(theta, t_min) ** 2, dtype=np.float64)

    def may_be_glared(self, mount: Mount, conditions: Conditions) -> bool:
        """True when the sun is in or within ``glare_margin_deg`` of the field of view."""
        return self.glare_weight(mount, conditions) > 0.0

    def prepare(self, mount: Mount, target: TargetConfig, conditions: Conditions) -> PreparedSensor:
        """Fold eq. 6-10 constants; the glare term only when the sun can reach this camera."""
        p = self.params
        h_nu = PLANCK_J_S * SPEED_OF_LIGHT_M_S / p.wavelength_m
        conv = p.integration_time_s * p.quantum_efficiency / h_nu  # electrons per W received
        ifov = max(mount.hfov / p.pixels_h, _MIN_IFOV_RAD)
        focal = p.pixel_pitch_m / ifov
        aperture = focal / p.f_number
        n_pix_db = 10.0 * math.log10(float(p.pixels_h) * float(p.pixels_v))
        env = conditions.env
        effects: dict[str, str] = {}
        irr = env.irradiance_w_m2
        if irr <= 0.0:
            effects["dark"] = "no irradiance on the object: camera SNR at its floor"
        sigma_db = 10.0 * math.log10(target.camera_cross_section_m2)
        terms = {
            "E_sun [dBW/m2]": 10.0 * math.log10(max(irr, 1e-300)),
            "sigma_cam [dBsm]": sigma_db,
            "rho/pi [dB]": 10.0 * math.log10(target.camera_reflectance / math.pi),
            "D^2 [dB m2]": 20.0 * math.log10(aperture),
            "-16 [dB]": -10.0 * math.log10(16.0),
            "-N_pix [dB]": -n_pix_db,
            "-L_sys [dB]": -p.system_loss_db,
            "t QE/(h nu) [dB 1/J]": 10.0 * math.log10(conv),
        }
        k_db = math.fsum(terms.values())
        thermal = BOLTZMANN_J_K * p.noise_bandwidth_hz * p.system_noise_temperature_k * conv
        w = self.glare_weight(mount, conditions)
        e_dir = 0.0  # direct-sun irradiance at the camera, W/m2 (0: no glare possible)
        if env.sun is not None and env.sun.visible:
            e_dir = env.sun.direct_irradiance_w_m2
        # veil-to-object radiance ratio at theta_min: k E_dir / theta_min^2 / (rho E / pi)
        t_min = p.veiling_glare_min_deg
        ln_veil0 = (
            math.log(max(p.veiling_glare_k * e_dir, 1e-300))
            - 2.0 * math.log(t_min)
            + math.log(math.pi / (target.camera_reflectance * max(irr, 1e-300)))
        )
        glare = e_dir > 0.0 and p.veiling_glare_k > 0.0
        ln_thermal = math.log(thermal)
        gamma = conditions.attenuation_db_km(self.band())
        # object -> camera: one pass (Koschmieder)
        losses = RangeLosses.of(gamma, 1.0, mount, p.fov_edge_loss_db)
        one_way_db_m = losses.weather_db_m
        ifov_db = 20.0 * math.log10(ifov)
        edge, hfov, vfov = losses.edge_loss_db, losses.hfov, losses.vfov
        sun_s = None  # this scene's sun in the sensor frame, when it reaches this camera
        if w > 0.0 and glare and conditions.sun_direction is not None:
            sun_s = mount.rotation().T @ np.asarray(conditions.sun_direction, dtype=np.float64)
            off = math.degrees(angle_outside_fov(mount, conditions.sun_direction))
            effects["glare"] = (
                f"sun {off:.1f} deg outside the view (weight {w:.3f}); "
                f"veiling glare {10.0 * ln_veil0 / math.log(10.0):.1f} dB of "
                f"the object's radiance at {t_min:g} deg from the sun, "
                "falling as 1/theta^2; its contrast noise "
                f"{p.veil_contrast_noise:g} of the veil, averaged over up to "
                f"{p.veil_summation_px:g} pixels"
            )

        def signal_db(r: F64, az: F64, el: F64) -> F64:
            lr20 = 20.0 * np.log10(r)
            npo_db = np.minimum(sigma_db - lr20 - ifov_db, n_pix_db)
            return np.asarray(losses.apply(k_db + npo_db, lr20, r, az, el), dtype=np.float64)

        ln_cv = math.log(max(p.veil_contrast_noise, 1e-300))
        sum_db = 10.0 * math.log10(p.veil_summation_px)

        def snr_from_signal(ne_db: F64, g: F64, r: F64) -> F64:
            ln_ne = ne_db * LN10_OVER_10
            # N_veil over the object's image, then per covered pixel n_c / N_pix,o
            npo_db = np.minimum(
                sigma_db - 20.0 * np.log10(np.maximum(r, 1e-300)) - ifov_db, n_pix_db
            )
            cov_db = np.maximum(npo_db, 0.0)
            ln_veil = (
                np.log(np.maximum(g, 1e-300))
                + ln_veil0
                + ln_ne
                + (one_way_db_m * r + cov_db - npo_db) * LN10_OVER_10
            )
            ln_shot = 0.5 * np.logaddexp(ln_ne, ln_veil)
            ln_contrast = ln_cv + ln_veil - 0.5 * np.minimum(cov_db, sum_db) * LN10_OVER_10
            ln_noise = np.logaddexp(ln_shot, np.logaddexp(ln_thermal, ln_contrast))
            return np.asarray((ln_ne - ln_noise) / LN10_OVER_10, dtype=np.float64)

        def snr_db_glare(r: F64, az: F64, el: F64, g: F64) -> F64:
            return snr_from_signal(signal_db(r, az, el), g, r)

        def snr_db(r: F64, az: F64, el: F64) -> F64:
            ne_db = signal_db(r, az, el)
            if sun_s is not None:
                ce = np.cos(el)
                cos_sep = (
                    ce * np.cos(az) * sun_s[0] + ce * np.sin(az) * sun_s[1] + np.sin(el) * sun_s[2]
                )
                return snr_from_signal(ne_db, w * self.glare_falloff(cos_sep), r)
            ln_ne = ne_db * LN10_OVER_10
            ln_noise = np.logaddexp(0.5 * ln_ne, ln_thermal)
            return np.asarray((ln_ne - ln_noise) / LN10_OVER_10, dtype=np.float64)

        terms["N_thermal [dB e-]"] = 10.0 * math.log10(thermal)
        if glare:
            terms[f"veil/object at {t_min:g} deg [dB]"] = 10.0 * ln_veil0 / math.log(10.0)
            terms["veil contrast noise c_v [dB]"] = 10.0 * ln_cv / math.log(10.0)
            terms["veil summation n_sum [dB px]"] = sum_db
        terms["weather one-way [dB/km]"] = gamma
        terms["focal length [mm]"] = focal * 1e3
        return PreparedSensor(
            snr_db=snr_db,
            terms_db=terms,
            effects=effects,
            uses_angles=losses.uses_angles or sun_s is not None,
            snr_db_glare=snr_db_glare if glare else None,
            signal_db=signal_db if glare else None,
            snr_from_signal=snr_from_signal if glare else None,
            veil_constants=(
                (ln_veil0, ln_thermal, one_way_db_m, t_min, sigma_db, ifov_db, n_pix_db)
                + (ln_cv, sum_db)
                if glare
                else None
            ),
            signal_constants=(
                (k_db, sigma_db, ifov_db, n_pix_db, one_way_db_m, edge, hfov, vfov)
                if glare
                else None
            ),
        )
