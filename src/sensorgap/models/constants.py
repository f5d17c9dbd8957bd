"""Physical constants (SI, exact values of the 2019 SI redefinition, CODATA 2018)."""

BOLTZMANN_J_K = 1.380649e-23  #: k, J/K (exact, SI 2019)
PLANCK_J_S = 6.62607015e-34  #: h, J s (exact, SI 2019)
SPEED_OF_LIGHT_M_S = 299_792_458.0  #: c, m/s (exact)
T0_K = 290.0  #: IEEE standard reference temperature for noise figures, K (IEEE Std 145)


def speed_of_sound_m_s(temperature_c: float) -> float:
    """Speed of sound in dry air, m/s: 331.3 sqrt(1 + T/273.15) (ISO 9613-1 / textbook)."""
    return 331.3 * (1.0 + temperature_c / 273.15) ** 0.5
