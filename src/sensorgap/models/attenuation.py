"""Weather and air attenuation for radar, lidar, camera and ultrasonic sensors.

Every function returns the ONE-WAY specific attenuation gamma in dB/km as a Python float
(a round trip over range R costs ``2 gamma R``). Units of the arguments: frequency Hz,
wavelength m, rain and snow rate mm/h (snow as liquid-water equivalent), visibility m
(meteorological optical range, 2 % contrast), liquid water content g/m3, temperature degC,
pressure hPa, water-vapour density g/m3, relative humidity %.

Sources (the formulas are implemented here from the publications, no third-party code):

* radar rain: ITU-R P.838-3 (03/2005), eqs. (1)-(5), Tables 1-4;
* radar fog/cloud: ITU-R P.840-8 (08/2019) section 2, double-Debye model (same K_l in -6/-7/-8);
* radar clear air: ITU-R P.676-12 (08/2019) Annex 1 line-by-line, Tables 1-2;
* fog liquid water from visibility: Kunkel (1984) with Koschmieder's law;
* optical fog/haze/clear air: Kim, McArthur & Korevaar (2001), alternatively Kruse (1962);
* optical rain: Carbonneau & Wisely (1998);
* optical snow: ITU-R P.1817-1 (02/2012);
* radar snow: an ESTIMATE after Gunn & East (1954) (no ITU-R recommendation exists);
* ultrasonic: ISO 9613-1:1993 and the constant of Ponn et al. (2019).

Invalid input (non-numeric, non-finite, negative rate, visibility <= 0, out of the
documented domain) raises ``ValueError``. Within the domain every result is finite and no
floating-point warning is raised. Formulas, validity ranges and a table of values for the
presets: ``docs/attenuation.md``.
"""

from __future__ import annotations

import math
from typing import Final, Literal

__all__ = [
    "FOG_VISIBILITY_LIMIT_M",
    "MAX_LWC_G_M3",
    "MAX_PRECIP_MM_H",
    "MIN_VISIBILITY_M",
    "ULTRASONIC_DB_KM",
    "fog_kl_db_km_per_g_m3",
    "fog_lwc_from_visibility_g_m3",
    "fog_radar_db_km",
    "gaseous_components_db_km",
    "gaseous_db_km",
    "optical_fog_db_km",
    "optical_rain_db_km",
    "optical_snow_db_km",
    "rain_k_alpha",
    "rain_radar_db_km",
    "snow_radar_db_km",
    "ultrasonic_air_db_km",
]

# --------------------------------------------------------------------------------------------
# Constants and domain limits
# --------------------------------------------------------------------------------------------

#: dB per neper of power: 10 log10(e) = 4.3429...; turns an extinction coefficient in 1/km
#: into dB/km.
DB_PER_NEPER: Final[float] = 10.0 / math.log(10.0)

#: Koschmieder's constant ln(1 / 0.02) = 3.912: visibility (meteorological optical range)
#: is the distance over which a black object's contrast falls to 2 %, V = 3.912 / beta.
KOSCHMIEDER_2PCT: Final[float] = 3.912

#: Visibility below which the atmosphere is fog (WMO definition: < 1 km). Above it the
#: obscurant is haze or mist, whose liquid water content is negligible for radar: callers
#: should then take LWC ~ 0 instead of ``fog_lwc_from_visibility_g_m3``.
FOG_VISIBILITY_LIMIT_M: Final[float] = 1000.0

#: Ultrasonic air attenuation used by the paper, dB/km, weather-independent: Ponn et al.
#: (2019) after Sonbul & Kalashnikov (2014) (about 1 dB/m at ~48 kHz). The physics of the
#: same absorption as a function of temperature and humidity: ``ultrasonic_air_db_km``.
ULTRASONIC_DB_KM: Final[float] = 1000.0

#: Domain guards. They are numerical, not meteorological: they keep every power law and
#: exponential finite. The physical ranges of the models are narrower (see each docstring).
MAX_PRECIP_MM_H: Final[float] = 1.0e4  #: rain / snow rate upper bound, mm/h (5x world record)
MAX_LWC_G_M3: Final[float] = 1.0e6  #: liquid water content bound, g/m3 (= bulk water)
MIN_VISIBILITY_M: Final[float] = 1.0e-3  #: smallest accepted visibility, m
RADIO_MIN_HZ: Final[float] = 1.0e9  #: P.838 / P.676 Annex 1 frequency range: 1-1000 GHz
RADIO_MAX_HZ: Final[float] = 1.0e12
OPTICAL_MIN_M: Final[float] = 200.0e-9  #: accepted optical wavelengths: 0.2-20 um
OPTICAL_MAX_M: Final[float] = 20.0e-6
ACOUSTIC_MAX_HZ: Final[float] = 1.0e7  #: ultrasonic frequency guard, Hz
TEMPERATURE_MIN_C: Final[float] = -100.0  #: temperature guard, degC
TEMPERATURE_MAX_C: Final[float] = 100.0
PRESSURE_MAX_HPA: Final[float] = 2000.0  #: pressure guard, hPa (ISO 9613-1: < 200 kPa)
MAX_WATER_VAPOUR_G_M3: Final[float] = 1000.0  #: water-vapour density guard, g/m3

_KELVIN: Final[float] = 273.15

FogModel = Literal["kim", "kruse"]


# --------------------------------------------------------------------------------------------
# Input validation
# --------------------------------------------------------------------------------------------


def _real(name: str, value: object) -> float:
    """``value`` as a finite Python float, else ``ValueError`` naming ``name``."""
    if isinstance(value, str | bytes):
        raise ValueError(f"{name} must be a real number, got {value!r}")
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a real number, got {value!r}") from exc
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {x!r}")
    return x


def _bounded(name: str, value: object, lo: float, hi: float, unit: str) -> float:
    """A finite float in the closed interval [lo, hi], else ``ValueError``."""
    x = _real(name, value)
    if not lo <= x <= hi:
        raise ValueError(f"{name} must be in [{lo:g}, {hi:g}] {unit}, got {x!r}")
    return x


def _rate(name: str, value: object) -> float:
    """A precipitation rate, mm/h: 0 <= R <= MAX_PRECIP_MM_H."""
    x = _real(name, value)
    if x < 0.0:
        raise ValueError(f"{name} must be >= 0 mm/h, got {x!r}")
    if x > MAX_PRECIP_MM_H:
        raise ValueError(f"{name} must be <= {MAX_PRECIP_MM_H:g} mm/h, got {x!r}")
    return x


def _radio_ghz(frequency_hz: object) -> float:
    """Radar frequency in Hz, checked against 1-1000 GHz, returned in GHz."""
    f = _real("frequency_hz", frequency_hz)
    if not RADIO_MIN_HZ <= f <= RADIO_MAX_HZ:
        raise ValueError(
            f"frequency_hz must be in [{RADIO_MIN_HZ:g}, {RADIO_MAX_HZ:g}] Hz (1-1000 GHz), "
            f"got {f!r} (frequencies are in Hz, not GHz)"
        )
    return f * 1.0e-9


def _wavelength_nm(wavelength_m: object) -> float:
    """Optical wavelength in m, checked against 0.2-20 um, returned in nm."""
    lam = _real("wavelength_m", wavelength_m)
    if not OPTICAL_MIN_M <= lam <= OPTICAL_MAX_M:
        raise ValueError(
            f"wavelength_m must be in [{OPTICAL_MIN_M:g}, {OPTICAL_MAX_M:g}] m, got {lam!r} "
            "(wavelengths are in m, e.g. 905e-9)"
        )
    return lam * 1.0e9


def _visibility_km(visibility_m: object) -> float:
    """Visibility in m, > 0 (at least MIN_VISIBILITY_M), returned in km."""
    v = _real("visibility_m", visibility_m)
    if v <= 0.0:
        raise ValueError(f"visibility_m must be > 0 m, got {v!r}")
    if v < MIN_VISIBILITY_M:
        raise ValueError(f"visibility_m must be >= {MIN_VISIBILITY_M:g} m, got {v!r}")
    return v * 1.0e-3


def _temperature_c(temperature_c: object) -> float:
    return _bounded("temperature_c", temperature_c, TEMPERATURE_MIN_C, TEMPERATURE_MAX_C, "degC")


def _flag(name: str, value: object) -> bool:
    """A boolean flag (bool or numpy bool), else ``ValueError``."""
    if value is True or value is False:
        return bool(value)
    cls = type(value)
    if cls.__module__ == "numpy" and cls.__name__ in ("bool", "bool_"):  # numpy.bool_
        return bool(value)
    raise ValueError(f"{name} must be a bool, got {value!r}")


# --------------------------------------------------------------------------------------------
# Radar: rain, ITU-R P.838-3
# --------------------------------------------------------------------------------------------

# ITU-R P.838-3 (03/2005), Tables 1-4: (a_j, b_j, c_j) of the Gaussian terms, then the
# linear term (m, c), for log10 k (eq. 2) and for alpha (eq. 3); f in GHz.
_P838_KH: Final = (
    (
        (-5.33980, -0.10008, 1.13098),
        (-0.35351, 1.26970, 0.45400),
        (-0.23789, 0.86036, 0.15354),
        (-0.94158, 0.64552, 0.16817),
    ),
    -0.18961,
    0.71147,
)  # Table 1, k_H
_P838_KV: Final = (
    (
        (-3.80595, 0.56934, 0.81061),
        (-3.44965, -0.22911, 0.51059),
        (-0.39902, 0.73042, 0.11899),
        (0.50167, 1.07319, 0.27195),
    ),
    -0.16398,
    0.63297,
)  # Table 2, k_V
_P838_AH: Final = (
    (
        (-0.14318, 1.82442, -0.55187),
        (0.29591, 0.77564, 0.19822),
        (0.32177, 0.63773, 0.13164),
        (-5.37610, -0.96230, 1.47828),
        (16.1721, -3.29980, 3.43990),
    ),
    0.67849,
    -1.95537,
)  # Table 3, alpha_H
_P838_AV: Final = (
    (
        (-0.07771, 2.33840, -0.76284),
        (0.56727, 0.95545, 0.54039),
        (-0.20238, 1.14520, 0.26809),
        (-48.2991, 0.791669, 0.116226),
        (48.5833, 0.791459, 0.116479),
    ),
    -0.053739,
    0.83433,
)  # Table 4, alpha_V


def _p838_fit(
    table: tuple[tuple[tuple[float, float, float], ...], float, float], log10_f: float
) -> float:
    """sum_j a_j exp(-((log10 f - b_j) / c_j)^2) + m log10 f + c (P.838-3 eqs. 2-3)."""
    terms, m, c = table
    s = 0.0
    for a, b, cj in terms:
        s += a * math.exp(-(((log10_f - b) / cj) ** 2))
    return s + m * log10_f + c


def rain_k_alpha(
    frequency_hz: float, tilt_rad: float = 0.0, elevation_rad: float = 0.0
) -> tuple[float, float]:
    """Coefficients (k, alpha) of the rain power law gamma = k R^alpha.

    Source: ITU-R P.838-3 (03/2005): k_H, k_V from eq. (2) with Tables 1-2, alpha_H, alpha_V
    from eq. (3) with Tables 3-4, combined for a path elevation theta and a polarisation tilt
    tau (0 = horizontal, pi/2 = vertical, pi/4 = circular) by eqs. (4)-(5):
    ``k = [k_H + k_V + (k_H - k_V) cos^2(theta) cos(2 tau)] / 2``,
    ``alpha = [k_H a_H + k_V a_V + (k_H a_H - k_V a_V) cos^2(theta) cos(2 tau)] / (2 k)``.

    Args:
        frequency_hz: carrier frequency, Hz, 1e9..1e12 (the recommendation's 1-1000 GHz).
        tilt_rad: polarisation tilt angle relative to the horizontal, rad.
        elevation_rad: path elevation angle, rad (0 for a horizontal automotive path).

    Returns:
        ``(k, alpha)``: k in dB/km/(mm/h)^alpha, alpha dimensionless.
    """
    f_ghz = _radio_ghz(frequency_hz)
    tau = _real("tilt_rad", tilt_rad)
    theta = _real("elevation_rad", elevation_rad)
    lf = math.log10(f_ghz)
    k_h = 10.0 ** _p838_fit(_P838_KH, lf)
    k_v = 10.0 ** _p838_fit(_P838_KV, lf)
    a_h = _p838_fit(_P838_AH, lf)
    a_v = _p838_fit(_P838_AV, lf)
    w = math.cos(theta) ** 2 * math.cos(2.0 * tau)
    k = 0.5 * (k_h + k_v + (k_h - k_v) * w)
    alpha = (k_h * a_h + k_v * a_v + (k_h * a_h - k_v * a_v) * w) / (2.0 * k)
    return k, alpha


def rain_radar_db_km(
    frequency_hz: float, rain_mm_h: float, tilt_rad: float = 0.0, elevation_rad: float = 0.0
) -> float:
    """One-way specific attenuation of rain at radar frequencies, dB/km.

    Source: ITU-R P.838-3 (03/2005), eq. (1) ``gamma_R = k R^alpha`` with k, alpha from
    eqs. (2)-(5) and Tables 1-4 (see ``rain_k_alpha``). Valid 1-1000 GHz; the recommendation
    states no rain-rate limit (the power law is applied as is at any rate).

    Args:
        frequency_hz: carrier frequency, Hz (1e9..1e12).
        rain_mm_h: rain rate, mm/h (0..MAX_PRECIP_MM_H); 0 gives exactly 0.
        tilt_rad: polarisation tilt relative to horizontal, rad (default horizontal).
        elevation_rad: path elevation, rad (default horizontal path).

    Returns:
        gamma_R, dB/km (one way).
    """
    rate = _rate("rain_mm_h", rain_mm_h)
    k, alpha = rain_k_alpha(frequency_hz, tilt_rad, elevation_rad)
    if rate == 0.0:
        return 0.0
    return float(k * rate**alpha)


# --------------------------------------------------------------------------------------------
# Radar: fog and cloud liquid water, ITU-R P.840-8
# --------------------------------------------------------------------------------------------


def fog_kl_db_km_per_g_m3(frequency_hz: float, temperature_c: float = 15.0) -> float:
    """Liquid-water specific attenuation coefficient K_l, (dB/km)/(g/m3).

    Source: ITU-R P.840-8 (08/2019) section 2 (unchanged from P.840-6/-7), Rayleigh
    absorption by droplets with the double-Debye permittivity of water (Liebe, Hufford &
    Manabe 1991): eq. (2) ``K_l = 0.819 f / (eps'' (1 + eta^2))``, eq. (3)
    ``eta = (2 + eps') / eps''``, eqs. (4)-(5) for eps''(f), eps'(f), eqs. (6)-(11):
    ``theta = 300 / T``, ``eps0 = 77.66 + 103.3 (theta - 1)``, ``eps1 = 0.0671 eps0``,
    ``eps2 = 3.52``, ``f_p = 20.20 - 146 (theta - 1) + 316 (theta - 1)^2`` GHz,
    ``f_s = 39.8 f_p`` GHz. Computed as ``0.819 f eps'' / (eps''^2 + (2 + eps')^2)``,
    algebraically identical and free of division by a small eps''.
    Valid up to 1000 GHz for droplets small against the wavelength (fog, cloud).

    Args:
        frequency_hz: frequency, Hz (1e9..1e12).
        temperature_c: liquid water temperature, degC (-100..100; the permittivity model is
            fitted for about -20..+50 degC, supercooled fog down to about -8 degC is common).

    Returns:
        K_l in (dB/km)/(g/m3).
    """
    f = _radio_ghz(frequency_hz)
    t_k = _temperature_c(temperature_c) + _KELVIN
    th = 300.0 / t_k - 1.0
    eps0 = 77.66 + 103.3 * th
    eps1 = 0.0671 * eps0
    eps2 = 3.52
    fp = 20.20 - 146.0 * th + 316.0 * th * th
    fs = 39.8 * fp
    xp = f / fp
    xs = f / fs
    eps_im = (eps0 - eps1) * xp / (1.0 + xp * xp) + (eps1 - eps2) * xs / (1.0 + xs * xs)
    eps_re = (eps0 - eps1) / (1.0 + xp * xp) + (eps1 - eps2) / (1.0 + xs * xs) + eps2
    return float(0.819 * f * eps_im / (eps_im * eps_im + (2.0 + eps_re) ** 2))


def fog_radar_db_km(frequency_hz: float, lwc_g_m3: float, temperature_c: float = 15.0) -> float:
    """One-way specific attenuation of fog (or cloud) at radar frequencies, dB/km.

    Source: ITU-R P.840-8 (08/2019) eq. (1): ``gamma_c = K_l(f, T) M`` with M the liquid
    water content and K_l from eqs. (2)-(11) (see ``fog_kl_db_km_per_g_m3``).

    Args:
        frequency_hz: frequency, Hz (1e9..1e12).
        lwc_g_m3: liquid water content M, g/m3 (>= 0; fog is typically 0.01-0.5 g/m3).
        temperature_c: droplet temperature, degC.

    Returns:
        gamma_c, dB/km (one way).
    """
    lwc = _bounded("lwc_g_m3", lwc_g_m3, 0.0, MAX_LWC_G_M3, "g/m3")
    kl = fog_kl_db_km_per_g_m3(frequency_hz, temperature_c)
    return float(kl * lwc)


# --------------------------------------------------------------------------------------------
# Radar: clear air (oxygen and water vapour), ITU-R P.676-12 Annex 1
# --------------------------------------------------------------------------------------------

# ITU-R P.676-12 (08/2019) Annex 1, Table 1: spectroscopic data for oxygen attenuation,
# (f0 GHz, a1, a2, a3, a4, a5, a6); same values in P.676-13. Checked number by number against
# the ITU-Rpy 0.4.0 data file and CRC-COVLIB's ITURP_676.cpp transcriptions.
_OXYGEN_LINES: Final[tuple[tuple[float, float, float, float, float, float, float], ...]] = (
    (50.474214, 0.975, 9.651, 6.69, 0.0, 2.566, 6.85),
    (50.987745, 2.529, 8.653, 7.17, 0.0, 2.246, 6.8),
    (51.50336, 6.193, 7.709, 7.64, 0.0, 1.947, 6.729),
    (52.021429, 14.32, 6.819, 8.11, 0.0, 1.667, 6.64),
    (52.542418, 31.24, 5.983, 8.58, 0.0, 1.388, 6.526),
    (53.066934, 64.29, 5.201, 9.06, 0.0, 1.349, 6.206),
    (53.595775, 124.6, 4.474, 9.55, 0.0, 2.227, 5.085),
    (54.130025, 227.3, 3.8, 9.96, 0.0, 3.17, 3.75),
    (54.67118, 389.7, 3.182, 10.37, 0.0, 3.558, 2.654),
    (55.221384, 627.1, 2.618, 10.89, 0.0, 2.56, 2.952),
    (55.783815, 945.3, 2.109, 11.34, 0.0, -1.172, 6.135),
    (56.264774, 543.4, 0.014, 17.03, 0.0, 3.525, -0.978),
    (56.363399, 1331.8, 1.654, 11.89, 0.0, -2.378, 6.547),
    (56.968211, 1746.6, 1.255, 12.23, 0.0, -3.545, 6.451),
    (57.612486, 2120.1, 0.91, 12.62, 0.0, -5.416, 6.056),
    (58.323877, 2363.7, 0.621, 12.95, 0.0, -1.932, 0.436),
    (58.446588, 1442.1, 0.083, 14.91, 0.0, 6.768, -1.273),
    (59.164204, 2379.9, 0.387, 13.53, 0.0, -6.561, 2.309),
    (59.590983, 2090.7, 0.207, 14.08, 0.0, 6.957, -0.776),
    (60.306056, 2103.4, 0.207, 14.15, 0.0, -6.395, 0.699),
    (60.434778, 2438.0, 0.386, 13.39, 0.0, 6.342, -2.825),
    (61.150562, 2479.5, 0.621, 12.92, 0.0, 1.014, -0.584),
    (61.800158, 2275.9, 0.91, 12.63, 0.0, 5.014, -6.619),
    (62.41122, 1915.4, 1.255, 12.17, 0.0, 3.029, -6.759),
    (62.486253, 1503.0, 0.083, 15.13, 0.0, -4.499, 0.844),
    (62.997984, 1490.2, 1.654, 11.74, 0.0, 1.856, -6.675),
    (63.568526, 1078.0, 2.108, 11.34, 0.0, 0.658, -6.139),
    (64.127775, 728.7, 2.617, 10.88, 0.0, -3.036, -2.895),
    (64.67891, 461.3, 3.181, 10.38, 0.0, -3.968, -2.59),
    (65.224078, 274.0, 3.8, 9.96, 0.0, -3.528, -3.68),
    (65.764779, 153.0, 4.473, 9.55, 0.0, -2.548, -5.002),
    (66.302096, 80.4, 5.2, 9.06, 0.0, -1.66, -6.091),
    (66.836834, 39.8, 5.982, 8.58, 0.0, -1.68, -6.393),
    (67.369601, 18.56, 6.818, 8.11, 0.0, -1.956, -6.475),
    (67.900868, 8.172, 7.708, 7.64, 0.0, -2.216, -6.545),
    (68.431006, 3.397, 8.652, 7.17, 0.0, -2.492, -6.6),
    (68.960312, 1.334, 9.65, 6.69, 0.0, -2.773, -6.65),
    (118.750334, 940.3, 0.01, 16.64, 0.0, -0.439, 0.079),
    (368.498246, 67.4, 0.048, 16.4, 0.0, 0.0, 0.0),
    (424.76302, 637.7, 0.044, 16.4, 0.0, 0.0, 0.0),
    (487.249273, 237.4, 0.049, 16.0, 0.0, 0.0, 0.0),
    (715.392902, 98.1, 0.145, 16.0, 0.0, 0.0, 0.0),
    (773.83949, 572.3, 0.141, 16.2, 0.0, 0.0, 0.0),
    (834.145546, 183.1, 0.145, 14.7, 0.0, 0.0, 0.0),
)

# ITU-R P.676-12 (08/2019) Annex 1, Table 2: spectroscopic data for water-vapour attenuation,
# (f0 GHz, b1, b2, b3, b4, b5, b6); same values in P.676-13, checked as Table 1.
_WATER_VAPOUR_LINES: Final[tuple[tuple[float, float, float, float, float, float, float], ...]] = (
    (22.23508, 0.1079, 2.144, 26.38, 0.76, 5.087, 1.0),
    (67.80396, 0.0011, 8.732, 28.58, 0.69, 4.93, 0.82),
    (119.99594, 0.0007, 8.353, 29.48, 0.7, 4.78, 0.79),
    (183.310087, 2.273, 0.668, 29.06, 0.77, 5.022, 0.85),
    (321.22563, 0.047, 6.179, 24.04, 0.67, 4.398, 0.54),
    (325.152888, 1.514, 1.541, 28.23, 0.64, 4.893, 0.74),
    (336.227764, 0.001, 9.825, 26.93, 0.69, 4.74, 0.61),
    (380.197353, 11.67, 1.048, 28.11, 0.54, 5.063, 0.89),
    (390.134508, 0.0045, 7.347, 21.52, 0.63, 4.81, 0.55),
    (437.346667, 0.0632, 5.048, 18.45, 0.6, 4.23, 0.48),
    (439.150807, 0.9098, 3.595, 20.07, 0.63, 4.483, 0.52),
    (443.018343, 0.192, 5.048, 15.55, 0.6, 5.083, 0.5),
    (448.001085, 10.41, 1.405, 25.64, 0.66, 5.028, 0.67),
    (470.888999, 0.3254, 3.597, 21.34, 0.66, 4.506, 0.65),
    (474.689092, 1.26, 2.379, 23.2, 0.65, 4.804, 0.64),
    (488.490108, 0.2529, 2.852, 25.86, 0.69, 5.201, 0.72),
    (503.568532, 0.0372, 6.731, 16.12, 0.61, 3.98, 0.43),
    (504.482692, 0.0124, 6.731, 16.12, 0.61, 4.01, 0.45),
    (547.67644, 0.9785, 0.158, 26.0, 0.7, 4.5, 1.0),
    (552.02096, 0.184, 0.158, 26.0, 0.7, 4.5, 1.0),
    (556.935985, 497.0, 0.159, 30.86, 0.69, 4.552, 1.0),
    (620.700807, 5.015, 2.391, 24.38, 0.71, 4.856, 0.68),
    (645.766085, 0.0067, 8.633, 18.0, 0.6, 4.0, 0.5),
    (658.00528, 0.2732, 7.816, 32.1, 0.69, 4.14, 1.0),
    (752.033113, 243.4, 0.396, 30.86, 0.68, 4.352, 0.84),
    (841.051732, 0.0134, 8.177, 15.9, 0.33, 5.76, 0.45),
    (859.965698, 0.1325, 8.055, 30.6, 0.68, 4.09, 0.84),
    (899.303175, 0.0547, 7.914, 29.85, 0.68, 4.53, 0.9),
    (902.611085, 0.0386, 8.429, 28.65, 0.7, 5.1, 0.95),
    (906.205957, 0.1836, 5.11, 24.08, 0.7, 4.7, 0.53),
    (916.171582, 8.4, 1.441, 26.73, 0.7, 5.15, 0.78),
    (923.112692, 0.0079, 10.293, 29.0, 0.7, 5.0, 0.8),
    (970.315022, 9.009, 1.919, 25.5, 0.64, 4.94, 0.67),
    (987.926764, 134.6, 0.257, 29.85, 0.68, 4.55, 0.9),
    (1780.0, 17506.0, 0.952, 196.3, 2.0, 24.15, 5.0),
)


def _line_shape(f: float, fi: float, width: float, delta: float) -> float:
    """Line shape factor F_i of ITU-R P.676-12 Annex 1 eq. (5), GHz^-1."""
    d_minus = fi - f
    d_plus = fi + f
    w2 = width * width
    return (f / fi) * (
        (width - delta * d_minus) / (d_minus * d_minus + w2)
        + (width - delta * d_plus) / (d_plus * d_plus + w2)
    )


def gaseous_components_db_km(
    frequency_hz: float,
    pressure_hpa: float = 1013.25,
    temperature_c: float = 15.0,
    water_vapour_g_m3: float = 7.5,
) -> tuple[float, float]:
    """Oxygen (dry air) and water-vapour specific attenuation, dB/km, as a pair.

    Source: ITU-R P.676-12 (08/2019) Annex 1 section 1, line-by-line summation, eqs. (1)-(9)
    (unchanged in P.676-13), line data of Tables 1 (44 oxygen lines) and 2 (35 water-vapour
    lines):

    * ``gamma = gamma_o + gamma_w = 0.1820 f (N''_Oxygen + N''_WaterVapour)`` (eq. 1);
    * ``N''_Oxygen = sum_i S_i F_i + N''_D``, ``N''_WaterVapour = sum_i S_i F_i`` (eq. 2);
    * oxygen ``S_i = a1 1e-7 p theta^3 exp(a2 (1 - theta))``, water vapour
      ``S_i = b1 1e-1 e theta^3.5 exp(b2 (1 - theta))`` (eq. 3), ``theta = 300 / T``;
    * ``F_i = f/f_i [(df - delta (f_i - f)) / ((f_i - f)^2 + df^2)
      + (df - delta (f_i + f)) / ((f_i + f)^2 + df^2)]`` (eq. 5);
    * oxygen ``df = a3 1e-4 (p theta^(0.8 - a4) + 1.1 e theta)``, then
      ``df = sqrt(df^2 + 2.25e-6)`` (Zeeman), ``delta = (a5 + a6 theta) 1e-4 (p + e)
      theta^0.8``; water vapour ``df = b3 1e-4 (p theta^b4 + b5 e theta^b6)``, then
      ``df = 0.535 df + sqrt(0.217 df^2 + 2.1316e-12 f_i^2 / theta)`` (Doppler),
      ``delta = 0`` (eqs. 6-7);
    * dry continuum ``N''_D = f p theta^2 [6.14e-5 / (d (1 + (f/d)^2))
      + 1.4e-12 p theta^1.5 / (1 + 1.9e-5 f^1.5)]``, ``d = 5.6e-4 (p + e) theta^0.8``
      (eqs. 8-9);
    * ``e = rho T / 216.7`` hPa (water-vapour partial pressure, eq. 4).

    In the recommendation p is the DRY-air pressure and the total barometric pressure is
    ``p + e``. ``pressure_hpa`` here is the TOTAL barometric pressure (what a weather report
    gives): p = pressure_hpa - e. (ITU-Rpy's ``gamma0_exact(f, P, ...)`` takes P as the dry
    pressure, so at P = 1013.25 hPa, 7.5 g/m3, 15 degC it gives oxygen 2 % higher than here.)
    Valid 1-1000 GHz.

    Args:
        frequency_hz: frequency, Hz (1e9..1e12).
        pressure_hpa: total barometric pressure, hPa (0 < P <= 2000, P > e).
        temperature_c: air temperature, degC (-100..100).
        water_vapour_g_m3: water-vapour density rho, g/m3 (>= 0).

    Returns:
        ``(gamma_o, gamma_w)``, dB/km (one way each).
    """
    f = _radio_ghz(frequency_hz)
    p_tot = _real("pressure_hpa", pressure_hpa)
    if not 0.0 < p_tot <= PRESSURE_MAX_HPA:
        raise ValueError(f"pressure_hpa must be in (0, {PRESSURE_MAX_HPA:g}] hPa, got {p_tot!r}")
    t_k = _temperature_c(temperature_c) + _KELVIN
    rho = _bounded("water_vapour_g_m3", water_vapour_g_m3, 0.0, MAX_WATER_VAPOUR_G_M3, "g/m3")
    e = rho * t_k / 216.7
    if e >= p_tot:
        raise ValueError(
            f"water-vapour partial pressure e = {e:.4g} hPa (rho = {rho:g} g/m3 at "
            f"{t_k - _KELVIN:g} degC) must be below the total pressure {p_tot:g} hPa"
        )
    p = p_tot - e
    theta = 300.0 / t_k

    # Oxygen lines (Table 1) and the dry continuum.
    width_p = p * theta**0.8
    width_e = 1.1 * e * theta
    shift = 1.0e-4 * (p + e) * theta**0.8
    s_common = 1.0e-7 * p * theta**3
    n_ox = 0.0
    for fi, a1, a2, a3, a4, a5, a6 in _OXYGEN_LINES:
        df = a3 * 1.0e-4 * (width_p * theta ** (-a4) + width_e)
        df = math.sqrt(df * df + 2.25e-6)
        delta = (a5 + a6 * theta) * shift
        n_ox += a1 * s_common * math.exp(a2 * (1.0 - theta)) * _line_shape(f, fi, df, delta)
    d = 5.6e-4 * (p + e) * theta**0.8
    # 6.14e-5 / (d (1 + (f/d)^2)) written as 6.14e-5 d / (d^2 + f^2): finite as d -> 0.
    n_d = (
        f
        * p
        * theta**2
        * (6.14e-5 * d / (d * d + f * f) + 1.4e-12 * p * theta**1.5 / (1.0 + 1.9e-5 * f**1.5))
    )
    n_ox += n_d

    # Water-vapour lines (Table 2).
    s_w = 1.0e-1 * e * theta**3.5
    n_w = 0.0
    if e > 0.0:
        for fi, b1, b2, b3, b4, b5, b6 in _WATER_VAPOUR_LINES:
            df = b3 * 1.0e-4 * (p * theta**b4 + b5 * e * theta**b6)
            df = 0.535 * df + math.sqrt(0.217 * df * df + 2.1316e-12 * fi * fi / theta)
            n_w += b1 * s_w * math.exp(b2 * (1.0 - theta)) * _line_shape(f, fi, df, 0.0)

    gamma_o = 0.1820 * f * n_ox
    gamma_w = 0.1820 * f * n_w
    # The line-mixing terms (delta) can make single lines negative; the sums stay positive
    # over the whole domain (scanned: 1-1000 GHz, 1-2000 hPa, -100..100 degC, 0-50 g/m3). The
    # clamp only guarantees the documented non-negative result.
    return float(max(gamma_o, 0.0)), float(max(gamma_w, 0.0))


def gaseous_db_km(
    frequency_hz: float,
    pressure_hpa: float = 1013.25,
    temperature_c: float = 15.0,
    water_vapour_g_m3: float = 7.5,
) -> float:
    """One-way specific attenuation of clear air (oxygen + water vapour), dB/km.

    Source: ITU-R P.676-12 (08/2019) Annex 1, eq. (1) ``gamma = gamma_o + gamma_w`` by the
    line-by-line summation of eqs. (2)-(9) with Tables 1-2 (see
    ``gaseous_components_db_km``). Valid 1-1000 GHz. Standard ground atmosphere:
    1013.25 hPa, 15 degC, 7.5 g/m3.

    Args:
        frequency_hz: frequency, Hz (1e9..1e12).
        pressure_hpa: TOTAL barometric pressure, hPa (dry-air pressure is P - e).
        temperature_c: air temperature, degC.
        water_vapour_g_m3: water-vapour density, g/m3.

    Returns:
        gamma, dB/km (one way).
    """
    g_o, g_w = gaseous_components_db_km(
        frequency_hz, pressure_hpa, temperature_c, water_vapour_g_m3
    )
    return g_o + g_w


# --------------------------------------------------------------------------------------------
# Fog liquid water from visibility, Kunkel (1984)
# --------------------------------------------------------------------------------------------


def fog_lwc_from_visibility_g_m3(visibility_m: float) -> float:
    """Fog liquid water content estimated from the visibility, g/m3.

    Source: Kunkel, B. A. (1984), "Parameterization of droplet terminal velocity and
    extinction coefficient in fog models", J. Climate Appl. Meteor. 23, 34-41: visible
    extinction ``beta = 144.7 LWC^0.88`` (beta in 1/km, LWC in g/m3), with Koschmieder's law
    at 2 % contrast ``V = 3.912 / beta`` (V in km). Inverted:
    ``LWC = (3.912 / (144.7 V))^(1 / 0.88)``.

    The fit is for fog (V < 1 km). The formula value is returned for any visibility, but
    above ``FOG_VISIBILITY_LIMIT_M`` (haze, mist, clear air: the extinction is not by fog
    droplets) the caller should take LWC ~ 0 (the formula gives 0.017 g/m3 at 1 km and
    5e-4 g/m3 at 23 km).

    Args:
        visibility_m: meteorological optical range (visibility), m (> 0).

    Returns:
        liquid water content, g/m3 (e.g. ~0.5 at 50 m, ~0.05 at 300-380 m).
    """
    v_km = _visibility_km(visibility_m)
    beta = KOSCHMIEDER_2PCT / v_km
    return float((beta / 144.7) ** (1.0 / 0.88))


# --------------------------------------------------------------------------------------------
# Optical: fog, haze, clear air (Kim 2001 / Kruse 1962)
# --------------------------------------------------------------------------------------------


def _q_kim(v_km: float) -> float:
    """Size-distribution exponent q of Kim, McArthur & Korevaar (2001)."""
    if v_km > 50.0:
        return 1.6
    if v_km > 6.0:
        return 1.3
    if v_km > 1.0:
        return 0.16 * v_km + 0.34
    if v_km > 0.5:
        return v_km - 0.5
    return 0.0


def _q_kruse(v_km: float) -> float:
    """Size-distribution exponent q of Kruse et al. (1962)."""
    if v_km > 50.0:
        return 1.6
    if v_km > 6.0:
        return 1.3
    return 0.585 * v_km ** (1.0 / 3.0)


def optical_fog_db_km(wavelength_m: float, visibility_m: float, model: FogModel = "kim") -> float:
    """One-way specific attenuation of fog, haze or clear air at optical wavelengths, dB/km.

    Source: Kim, I. I., McArthur, B. & Korevaar, E. (2001), "Comparison of laser beam
    propagation at 785 nm and 1550 nm in fog and haze for optical wireless communications",
    Proc. SPIE 4214, 26-37: ``beta = (3.912 / V) (lambda / 550 nm)^(-q)`` (beta in 1/km, V in
    km) with ``q = 1.6`` (V > 50 km), ``1.3`` (6 < V <= 50 km), ``0.16 V + 0.34``
    (1 < V <= 6 km), ``V - 0.5`` (0.5 < V <= 1 km), ``0`` (V <= 0.5 km: dense fog attenuates
    all wavelengths alike). ``model="kruse"``: Kruse, McGlauchlin & McQuistan (1962),
    "Elements of Infrared Technology", Wiley: ``q = 0.585 V^(1/3)`` for V <= 6 km, 1.3 and
    1.6 above as Kim. Converted with ``gamma = 10 log10(e) beta = 4.343 beta`` dB/km.

    Valid for visible and near-infrared wavelengths (the fits use 0.5-1.6 um data); q jumps
    from 1.3 to 1.6 at V = 50 km (Kruse also at 6 km), so gamma(V) is non-increasing only for
    wavelengths >= 550 nm. Molecular absorption is not included (negligible at 905/1550 nm
    windows).

    Args:
        wavelength_m: wavelength, m (2e-7..2e-5).
        visibility_m: meteorological optical range, m (> 0; 23 km = standard clear air).
        model: ``"kim"`` (default) or ``"kruse"``.

    Returns:
        gamma, dB/km (one way).
    """
    lam_nm = _wavelength_nm(wavelength_m)
    v_km = _visibility_km(visibility_m)
    if model == "kim":
        q = _q_kim(v_km)
    elif model == "kruse":
        q = _q_kruse(v_km)
    else:
        raise ValueError(f"model must be 'kim' or 'kruse', got {model!r}")
    beta = KOSCHMIEDER_2PCT / v_km * math.exp(-q * math.log(lam_nm / 550.0))
    return float(DB_PER_NEPER * beta)


# --------------------------------------------------------------------------------------------
# Optical: rain (Carbonneau 1998) and snow (ITU-R P.1817-1)
# --------------------------------------------------------------------------------------------


def optical_rain_db_km(rain_mm_h: float) -> float:
    """One-way specific attenuation of rain at optical wavelengths, dB/km.

    Source: Carbonneau, T. H. & Wisely, D. R. (1998), "Opportunities and challenges for
    optical wireless; the competitive advantage of free space telecommunications links in
    today's crowded marketplace", Proc. SPIE 3232: ``gamma = 1.076 R^0.67`` (R in mm/h), i.e.
    1.076 times R to the 0.67, NOT (1.076 R)^(2/3). Wavelength-independent (raindrops are
    much larger than the wavelength: geometric optics).

    Args:
        rain_mm_h: rain rate, mm/h (0..MAX_PRECIP_MM_H); 0 gives exactly 0.

    Returns:
        gamma, dB/km (one way): 3.16 at 5 mm/h, 9.30 at 25 mm/h.
    """
    rate = _rate("rain_mm_h", rain_mm_h)
    return float(1.076 * rate**0.67)


def optical_snow_db_km(wavelength_m: float, snow_mm_h: float, wet: bool) -> float:
    """One-way specific attenuation of snow at optical wavelengths, dB/km.

    Source: ITU-R P.1817-1 (02/2012), attenuation due to snow: ``gamma = a S^b`` with S the
    snow rate in mm/h and lambda in nm; wet snow ``a = 1.023e-4 lambda + 3.7855466``,
    ``b = 0.72``; dry snow ``a = 5.42e-5 lambda + 5.4958776``, ``b = 1.38``. The
    recommendation covers near-infrared free-space-optics wavelengths (~ 690-1550 nm); at
    550 nm it is an extrapolation (a changes by < 1 %).

    Args:
        wavelength_m: wavelength, m (2e-7..2e-5).
        snow_mm_h: snow rate, mm/h liquid-water equivalent (0..MAX_PRECIP_MM_H).
        wet: True for wet snow, False for dry snow.

    Returns:
        gamma, dB/km (one way): 905 nm wet 3.88 / 12.3 and dry 5.54 / 51.1 at 1 / 5 mm/h.
    """
    lam_nm = _wavelength_nm(wavelength_m)
    rate = _rate("snow_mm_h", snow_mm_h)
    if _flag("wet", wet):
        a, b = 1.023e-4 * lam_nm + 3.7855466, 0.72
    else:
        a, b = 5.42e-5 * lam_nm + 5.4958776, 1.38
    return float(a * rate**b)


# --------------------------------------------------------------------------------------------
# Radar: snow (ESTIMATE, no ITU-R recommendation)
# --------------------------------------------------------------------------------------------

_C_M_S: Final[float] = 299_792_458.0


def snow_radar_db_km(frequency_hz: float, snow_mm_h: float, wet: bool) -> float:
    """ESTIMATE of the one-way specific attenuation of snow at radar frequencies, dB/km.

    There is no ITU-R recommendation for snow attenuation. This is an estimate:

    * dry snow: Gunn, K. L. S. & East, T. W. R. (1954), "The microwave properties of
      precipitation particles", Q. J. R. Meteorol. Soc. 80, 522-545, as quoted by Battan
      (1973, "Radar Observation of the Atmosphere", ch. 6):
      ``gamma = 0.00349 R^1.6 / lambda^4 + 0.00224 R / lambda`` (dB/km; R snowfall rate in
      mm/h of melted water; lambda in cm). First term: Rayleigh scattering by ice
      particles, ``4.343e3 (2 pi^5 / 3) |K|^2 Z / lambda^4`` with Z = 200 R^1.6 mm^6/m^3 and
      |K|^2 ~ 0.2 (ice, melted-equivalent diameters); second term: Rayleigh absorption by
      ice, proportional to the ice mass content (~ R). Rayleigh requires particles small
      against the wavelength (lambda = 12 mm at 24 GHz, 3.9 mm at 77 GHz): at 77 GHz and
      above large aggregates violate it, and the lambda^-4 law then overestimates
      (Mie scattering saturates), so the 77 GHz value is an upper-side estimate.
    * wet snow: rain at the same liquid-equivalent rate (ITU-R P.838-3, horizontal
      polarisation). Melting snow is reported to attenuate at least as much as rain of the
      same liquid content, so this may underestimate wet snow; it is not a bound.

    Args:
        frequency_hz: frequency, Hz (1e9..1e12).
        snow_mm_h: snow rate, mm/h liquid-water equivalent (0..MAX_PRECIP_MM_H).
        wet: True for wet snow, False for dry snow.

    Returns:
        gamma, dB/km (one way). Dry: 24 GHz 0.0032 / 0.028, 77 GHz 0.16 / 2.0 at 1 / 5 mm/h.
    """
    is_wet = _flag("wet", wet)
    rate = _rate("snow_mm_h", snow_mm_h)
    f_ghz = _radio_ghz(frequency_hz)
    if is_wet:
        return rain_radar_db_km(frequency_hz, rate)
    lam_cm = _C_M_S / (f_ghz * 1.0e9) * 100.0
    return float(0.00349 * rate**1.6 / lam_cm**4 + 0.00224 * rate / lam_cm)


# --------------------------------------------------------------------------------------------
# Ultrasonic: ISO 9613-1:1993
# --------------------------------------------------------------------------------------------


def ultrasonic_air_db_km(
    frequency_hz: float,
    temperature_c: float,
    relative_humidity_pct: float,
    pressure_hpa: float = 1013.25,
) -> float:
    """Atmospheric absorption of sound (pure tone), one way, dB/km.

    Source: ISO 9613-1:1993, eqs. (3)-(5) with the saturation vapour pressure of Annex B
    (eqs. B.1-B.3): ``h = h_r (p_sat / p_r) / (p_a / p_r)`` (molar concentration of water
    vapour, %), ``p_sat / p_r = 10^(-6.8346 (T01 / T)^1.261 + 4.6151)``, T01 = 273.16 K;
    relaxation frequencies of oxygen ``f_rO = (p_a / p_r) (24 + 4.04e4 h (0.02 + h) /
    (0.391 + h))`` (eq. 3) and nitrogen ``f_rN = (p_a / p_r) (T / T0)^(-1/2) (9 + 280 h
    exp(-4.170 ((T / T0)^(-1/3) - 1)))`` (eq. 4); attenuation coefficient (eq. 5)
    ``alpha = 8.686 f^2 [1.84e-11 (p_a / p_r)^-1 (T / T0)^(1/2) + (T / T0)^(-5/2)
    (0.01275 exp(-2239.1 / T) / (f_rO + f^2 / f_rO) + 0.1068 exp(-3352.0 / T) /
    (f_rN + f^2 / f_rN))]`` dB/m, T0 = 293.15 K, p_r = 101.325 kPa.
    Stated accuracy +-10 % for h 0.05-5 %, -20..+50 degC, p < 200 kPa and
    4e-4 <= f / p_a <= 10 Hz/Pa, i.e. up to ~1 MHz at sea level, which includes automotive
    ultrasonic sensors (40-60 kHz). The paper's weather-independent value is
    ``ULTRASONIC_DB_KM``.

    Args:
        frequency_hz: frequency, Hz (0 < f <= 1e7).
        temperature_c: air temperature, degC (-100..100).
        relative_humidity_pct: relative humidity, % (0..100).
        pressure_hpa: ambient atmospheric pressure, hPa (0 < p <= 2000).

    Returns:
        alpha, dB/km (one way): 1.60e3 at 48 kHz, 20 degC, 50 % RH.
    """
    f = _real("frequency_hz", frequency_hz)
    if not 0.0 < f <= ACOUSTIC_MAX_HZ:
        raise ValueError(f"frequency_hz must be in (0, {ACOUSTIC_MAX_HZ:g}] Hz, got {f!r}")
    t_k = _temperature_c(temperature_c) + _KELVIN
    h_r = _bounded("relative_humidity_pct", relative_humidity_pct, 0.0, 100.0, "%")
    p_a = _real("pressure_hpa", pressure_hpa)
    if not 0.0 < p_a <= PRESSURE_MAX_HPA:
        raise ValueError(f"pressure_hpa must be in (0, {PRESSURE_MAX_HPA:g}] hPa, got {p_a!r}")
    p_rel = p_a / 1013.25
    t_rel = t_k / 293.15
    p_sat_rel = 10.0 ** (-6.8346 * (273.16 / t_k) ** 1.261 + 4.6151)
    h = h_r * p_sat_rel / p_rel
    fr_o = p_rel * (24.0 + 4.04e4 * h * (0.02 + h) / (0.391 + h))
    fr_n = (
        p_rel * t_rel**-0.5 * (9.0 + 280.0 * h * math.exp(-4.170 * (t_rel ** (-1.0 / 3.0) - 1.0)))
    )
    f2 = f * f
    alpha_db_m = (
        8.686
        * f2
        * (
            1.84e-11 / p_rel * t_rel**0.5
            + t_rel**-2.5
            * (
                0.01275 * math.exp(-2239.1 / t_k) / (fr_o + f2 / fr_o)
                + 0.1068 * math.exp(-3352.0 / t_k) / (fr_n + f2 / fr_n)
            )
        )
    )
    return float(alpha_db_m * 1000.0)
