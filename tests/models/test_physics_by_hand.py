"""Each sensor type against eq. 1-10 of Ponn et al. 2019 evaluated by hand in linear units.

The model works in dB; here every equation is written out again in plain linear SI
arithmetic (independent code path). Tolerance: 1e-9 dB (float64 rounding only).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensorgap.config import EnvironmentConfig, TargetConfig
from sensorgap.config.environment import SunConfig
from sensorgap.models import Conditions, Mount
from sensorgap.models.camera import Camera, CameraParams
from sensorgap.models.lidar import Lidar, LidarParams
from sensorgap.models.radar import Radar, RadarParams
from sensorgap.models.ultrasonic import Ultrasonic, UltrasonicParams

K = 1.380649e-23
H = 6.62607015e-34
C = 299792458.0
TOL_DB = 1e-9

TARGET = TargetConfig(
    name="t",
    rcs_m2=100.0,
    camera_cross_section_m2=2.7,
    length_m=4.5,
    width_m=1.8,
    height_m=1.5,
    reference_height_m=0.75,
    lidar_reflectance=0.1,
    camera_reflectance=0.15,
)
MOUNT = Mount(
    x=0.0,
    y=0.0,
    z=0.5,
    yaw=0.0,
    pitch=0.0,
    hfov=math.radians(30.0),
    vfov=math.radians(10.0),
    min_range=0.0,
    max_range=5000.0,
)


def cond(**kw: object) -> Conditions:
    return Conditions.from_config(EnvironmentConfig(name="t", **kw))  # type: ignore[arg-type]


def db(x: float) -> float:
    return 10.0 * math.log10(x)


def snr_at(prep_fn: object, r: float, az: float = 0.0, el: float = 0.0) -> float:
    out = prep_fn(np.array([r]), np.array([az]), np.array([el]))  # type: ignore[operator]
    return float(out[0])


@pytest.mark.parametrize("r", [5.0, 50.0, 180.0])
@pytest.mark.parametrize("az_deg", [0.0, 10.0])
@pytest.mark.parametrize("rain", [0.0, 25.0])
def test_radar_eq3(r: float, az_deg: float, rain: float) -> None:
    p = RadarParams(
        frequency_hz=76.5e9,
        tx_power_dbm=12.0,
        tx_gain_dbi=25.0,
        rx_gain_dbi=25.0,
        noise_bandwidth_hz=250e3,
        noise_figure_db=14.0,
        system_loss_db=4.0,
        fov_edge_loss_db=3.0,
    )
    c = cond(rain_mm_h=rain)
    model = Radar(p)
    gamma = c.attenuation_db_km(model.band())
    az = math.radians(az_deg)
    loss_one_way_db = 3.0 * (2 * az / MOUNT.hfov) ** 2
    g = 10 ** ((25.0 - loss_one_way_db) / 10)
    pe = 10 ** ((12.0 - 30.0) / 10)
    lam = C / 76.5e9
    t_sys = 290.0 * (10**1.4 - 1) + 290.0
    l_oa = 10 ** (4.0 / 10) * 10 ** (2 * gamma * r / 1000 / 10)
    snr = pe * g * g * 100.0 * lam**2 / ((4 * math.pi) ** 3 * r**4 * l_oa * K * 250e3 * t_sys)
    got = snr_at(model.prepare(MOUNT, TARGET, c).snr_db, r, az)
    assert got == pytest.approx(db(snr), abs=TOL_DB)


def test_ultrasonic_eq3_with_acoustic_wavelength() -> None:
    p = UltrasonicParams(
        frequency_hz=48e3,
        tx_power_dbm=20.0,
        tx_gain_dbi=12.0,
        rx_gain_dbi=12.0,
        noise_bandwidth_hz=2e3,
        system_noise_temperature_k=2e8,
        fov_edge_loss_db=0.0,
    )
    c = cond(temperature_c=20.0)
    lam = 331.3 * math.sqrt(1 + 20.0 / 273.15) / 48e3
    r = 3.0
    g = 10**1.2
    l_oa = 10 ** (2 * 1000.0 * r / 1000 / 10)  # paper: 1000 dB/km one way
    snr = 0.1 * g * g * 100.0 * lam**2 / ((4 * math.pi) ** 3 * r**4 * l_oa * K * 2e3 * 2e8)
    got = snr_at(Ultrasonic(p).prepare(MOUNT, TARGET, c).snr_db, r)
    assert got == pytest.approx(db(snr), abs=TOL_DB)


@pytest.mark.parametrize("law", ["min", "point"])
@pytest.mark.parametrize("r", [0.5, 20.0, 150.0, 3000.0])
def test_lidar_eq4_eq5(law: str, r: float) -> None:
    p = LidarParams(
        wavelength_m=905e-9,
        peak_power_w=75.0,
        beam_divergence_rad=2e-3,
        receiver_diameter_m=0.015,
        noise_bandwidth_hz=2e8,
        system_noise_temperature_k=290.0,
        system_loss_db=3.0,
        target_law=law,
    )  # type: ignore[arg-type]
    tgt = TARGET.model_copy(update={"rcs_m2": 1.0})
    c = cond(visibility_m=2000.0)
    model = Lidar(p)
    gamma = c.attenuation_db_km(model.band())
    theta = 2e-3
    sigma = 1.0
    if law == "min":
        sigma = min(1.0, 0.1 * math.pi * r**2 * theta**2)
    ar = math.pi * 0.015**2 / 4
    l_oa = 10 ** (3.0 / 10) * 10 ** (2 * gamma * r / 1000 / 10)
    pr = 75.0 * sigma * ar / (math.pi**2 * r**4 * theta**2 * l_oa)
    nu = C / 905e-9
    pn = 2 * H * nu * 2e8 + K * 2e8 * 290.0
    got = snr_at(model.prepare(MOUNT, tgt, c).snr_db, r)
    assert got == pytest.approx(db(pr / pn), abs=TOL_DB)


def camera_params(**kw: object) -> CameraParams:
    base = dict(
        wavelength_m=550e-9,
        pixels_h=1920,
        pixels_v=1080,
        pixel_pitch_m=3e-6,
        f_number=1.8,
        quantum_efficiency=0.6,
        integration_time_s=1e-3,
        noise_bandwidth_hz=1e3,
        system_noise_temperature_k=300.0,
        system_loss_db=1.0,
        fov_edge_loss_db=0.0,
        glare_margin_deg=10.0,
    )
    base.update(kw)
    return CameraParams(**base)  # type: ignore[arg-type]


def camera_by_hand(
    r: float,
    gamma: float,
    e_sun: float,
    hfov: float,
    sun_w: float,
    e_dir: float,
    theta_deg: float = 1.0,
    k_veil: float = 10.0,
    c_v: float = 0.25,
    n_sum: float = 2500.0,
) -> float:
    """Eq. 6-9 by hand; with ``sun_w`` > 0 the direct sun as veiling glare on the target's
    image (Stiles-Holladay, theta >= 1 deg; docs/models.md): the veil over the object's
    image ``N_veil = w (k E_dir / theta^2) / (rho E_sun / pi) N_e 10^(gamma R / 10)``, its
    shot noise over the pixels the object's light falls on (``n_c = max(N_pix,o, 1)``) and
    its contrast noise ``c_v N_veil (n_c / N_pix,o) / sqrt(min(n_c, n_sum))``."""
    ifov = hfov / 1920
    f = 3e-6 / ifov
    d = f / 1.8
    n_pix = 1920 * 1080
    n_pix_o = min(2.7 / (r * ifov) ** 2, n_pix)
    l_oa = 10 ** (1.0 / 10) * 10 ** (gamma * r / 1000 / 10)  # one pass
    pr = 0.15 / math.pi * e_sun * 2.7 * d**2 * n_pix_o / (16 * r**2 * l_oa * n_pix)  # eq. 6
    h_nu = H * C / 550e-9
    ne = pr * 1e-3 * 0.6 / h_nu  # eq. 7
    thermal = K * 1e3 * 300.0 * 1e-3 * 0.6 / h_nu
    l_veil = k_veil * e_dir / max(theta_deg, 1.0) ** 2  # per lux of the sun: cd/m2
    l_obj = 0.15 * e_sun / math.pi
    n_veil = sun_w * l_veil / l_obj * ne * 10 ** (gamma * r / 1000 / 10)
    n_c = max(n_pix_o, 1.0)
    shot = math.sqrt(ne + n_veil * n_c / n_pix_o)  # eq. 8 with the veil's photons
    contrast = c_v * n_veil * (n_c / n_pix_o) / math.sqrt(min(n_c, n_sum))
    return db(ne / (shot + thermal + contrast))  # eq. 9


@pytest.mark.parametrize("r", [0.3, 10.0, 100.0, 400.0])
def test_camera_eq6_to_9(r: float) -> None:
    mount = Mount(0.0, 0.0, 1.3, 0.0, 0.0, math.radians(50.0), math.radians(28.0), 0.0, 1000.0)
    c = cond(irradiance_w_m2=534.0)
    model = Camera(camera_params())
    gamma = c.attenuation_db_km(model.band())
    got = snr_at(model.prepare(mount, TARGET, c).snr_db, r)
    want = camera_by_hand(r, gamma, 534.0, math.radians(50.0), 0.0, 0.0)
    assert got == pytest.approx(want, abs=TOL_DB)


@pytest.mark.parametrize("r", [10.0, 50.0, 400.0, 6000.0])
@pytest.mark.parametrize(
    ("tgt_az", "tgt_el"), [(0.0, 0.0), (-10.0, 5.0), (-10.5, 5.2), (15.0, -3.0)]
)
def test_camera_veiling_glare_by_hand(r: float, tgt_az: float, tgt_el: float) -> None:
    """Sun at azimuth -10 deg, elevation 5 deg, inside a level 50 x 28 deg camera's view;
    the angle between sun and target from the spherical law of cosines (by hand). The
    object covers 130,000 pixels at 10 m (beyond the summation limit), 82 at 400 m and 0.6
    at 6 km (sub-pixel: its light falls on one pixel)."""
    mount = Mount(0.0, 0.0, 1.3, 0.0, 0.0, math.radians(50.0), math.radians(28.0), 0.0, 1e4)
    model = Camera(camera_params())
    sun_front = SunConfig(azimuth_deg=-10.0, elevation_deg=5.0, direct_irradiance_w_m2=480.0)
    c = cond(irradiance_w_m2=534.0, sun=sun_front)
    gamma = c.attenuation_db_km(model.band())
    got = snr_at(
        model.prepare(mount, TARGET, c).snr_db, r, math.radians(tgt_az), math.radians(tgt_el)
    )
    e1, e2 = math.radians(5.0), math.radians(tgt_el)
    theta = math.degrees(
        math.acos(
            math.sin(e1) * math.sin(e2)
            + math.cos(e1) * math.cos(e2) * math.cos(math.radians(-10.0 - tgt_az))
        )
    )
    want = camera_by_hand(r, gamma, 534.0, math.radians(50.0), 1.0, 480.0, theta)
    assert got == pytest.approx(want, abs=TOL_DB)


def test_camera_glare_falls_with_angle_from_the_sun() -> None:
    """A target next to the sun is bounded by its contrast against the veil, averaged over
    its pixels: SNR <= sqrt(N_pix,o) / (c_v V(1 deg)); 30 deg from the sun the veil is 900
    times weaker (1/theta^2) and the SNR within 1 dB of the sunless one (the veil is still
    a fifth of the object's light: its shot and contrast noise cost 0.6 dB); with the sun
    behind the camera (outside its view and margin) there is no glare term at all."""
    mount = Mount(0.0, 0.0, 1.3, 0.0, 0.0, math.radians(90.0), math.radians(28.0), 0.0, 1000.0)
    model = Camera(camera_params())
    sun_front = SunConfig(azimuth_deg=-10.0, elevation_deg=5.0, direct_irradiance_w_m2=480.0)
    c = cond(irradiance_w_m2=534.0, sun=sun_front)
    prep = model.prepare(mount, TARGET, c)
    gamma = c.attenuation_db_km(model.band())
    sunless = camera_by_hand(150.0, gamma, 534.0, math.radians(90.0), 0.0, 0.0)
    near = snr_at(prep.snr_db, 150.0, math.radians(-10.0), math.radians(5.0))
    far = snr_at(prep.snr_db, 150.0, math.radians(20.0), math.radians(5.0))
    # at the sun (theta held at 1 deg); 179 pixels at 150 m behind a 90-deg lens
    n_pix_o = 2.7 / (150.0 * math.radians(90.0) / 1920) ** 2
    v_1deg = 10.0 * 480.0 / (0.15 * 534.0 / math.pi)
    assert near < db(math.sqrt(n_pix_o) / (0.25 * v_1deg)) < 10.0  # below the ROC's 50 %
    assert far == pytest.approx(sunless, abs=1.0) and far > near + 10.0
    sun_behind = SunConfig(azimuth_deg=170.0, elevation_deg=5.0)
    prep = model.prepare(mount, TARGET, cond(irradiance_w_m2=534.0, sun=sun_behind))
    assert "glare" not in prep.effects
    assert snr_at(prep.snr_db, 50.0) == pytest.approx(
        camera_by_hand(50.0, gamma, 534.0, math.radians(90.0), 0.0, 0.0), abs=TOL_DB
    )


def test_a_large_image_sees_through_a_veil_as_bright_as_the_object() -> None:
    """The veil costs contrast, not the object: a car at 40 m (about 2,600 pixels behind a
    50-deg lens) keeps an SNR above 20 dB where the veil's radiance equals the object's,
    while the same car at 1 km (4 pixels) drops below the ROC's 50 % (10 dB) there. With
    contrast noise 1 and no averaging (``veil_contrast_noise`` 1, ``veil_summation_px``
    1: the veil counted as a copy of the object's signal) the bound is 1 / V at any size."""
    mount = Mount(0.0, 0.0, 1.3, 0.0, 0.0, math.radians(50.0), math.radians(28.0), 0.0, 2000.0)
    sun_front = SunConfig(azimuth_deg=-10.0, elevation_deg=5.0, direct_irradiance_w_m2=480.0)
    c = cond(irradiance_w_m2=534.0, sun=sun_front)
    # V(theta) = 1 where 10 E_dir / theta^2 = rho E_sun / pi
    theta = math.sqrt(10.0 * 480.0 / (0.15 * 534.0 / math.pi))
    az = math.radians(-10.0 + theta)  # along the horizon of the sun's elevation: ~theta
    el = math.radians(5.0)
    sep = math.degrees(
        math.acos(math.sin(el) ** 2 + math.cos(el) ** 2 * math.cos(math.radians(theta)))
    )
    v = 10.0 * 480.0 / sep**2 / (0.15 * 534.0 / math.pi)
    assert v == pytest.approx(1.0, abs=0.01)
    prep = Camera(camera_params()).prepare(mount, TARGET, c)
    assert snr_at(prep.snr_db, 40.0, az, el) > 20.0
    assert snr_at(prep.snr_db, 1000.0, az, el) < 10.0
    copy = Camera(camera_params(veil_contrast_noise=1.0, veil_summation_px=1.0))
    prep = copy.prepare(mount, TARGET, c)
    for r in (40.0, 1000.0):
        assert snr_at(prep.snr_db, r, az, el) < db(1.0 / v)


def test_camera_glare_weight_fades_outside_fov() -> None:
    mount = Mount(0.0, 0.0, 1.3, 0.0, 0.0, math.radians(50.0), math.radians(28.0), 0.0, 1000.0)
    model = Camera(camera_params(glare_margin_deg=10.0))
    w = []
    for az in (0.0, 25.0, 30.0, 35.0, 40.0):  # FOV edge at 25 deg, margin 10 deg
        c = cond(sun=SunConfig(azimuth_deg=az, elevation_deg=5.0))
        w.append(model.glare_weight(mount, c))
    assert w[0] == 1.0 and w[1] == 1.0
    assert w[2] == pytest.approx(math.cos(math.pi / 4) ** 2, abs=1e-12)  # 5 of 10 deg: 0.5
    assert w[3] == 0.0 and w[4] == 0.0
