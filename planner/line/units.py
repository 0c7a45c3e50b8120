"""Unit conversions, used once at the edges (loading, CLI, reports).

Multiply a railway-unit value by the constant to get SI; divide to go back.
1 km/h/s = 1/3.6 m/s².
"""
KMH = 1.0 / 3.6
"""1 km/h in m/s."""
KMH_S = 1.0 / 3.6
"""1 km/h/s in m/s²."""
KMH_S2 = 1.0 / 3.6
"""1 km/h/s² in m/s³."""
TONNE = 1000.0
"""1 t in kg."""
KN = 1000.0
"""1 kN in N."""
PERMIL = 1e-3
"""1 ‰ as a dimensionless rise per metre."""
KWH = 3.6e6
"""1 kWh in J."""


def kmh(v_ms):
    """m/s → km/h."""
    return v_ms * 3.6


def ms(v_kmh):
    """km/h → m/s."""
    return v_kmh / 3.6
