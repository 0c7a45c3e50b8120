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


def kmh_s(a_ms2: float) -> float:
    """m/s² → km/h/s, rounded to 1e-9 km/h/s: a level written 2.6 in a job comes back as the float 2.6
    (not 2.6000000000000005), so a dataset filters on the job's own value (``adhesion_kmh_s = 2.6``)."""
    return round(float(a_ms2) * 3.6, 9)


def kmh(v_ms):
    """m/s → km/h."""
    return v_ms * 3.6


def ms(v_kmh):
    """km/h → m/s."""
    return v_kmh / 3.6


def clock(t_s) -> str:
    """Seconds after midnight → ``HH:MM:SS`` clock text (rounded to the second; hours run past 24 after
    midnight, as the timetable writes them); ``""`` for no time (None, NaN).

    >>> clock(18145.0), clock(90600.0), clock(float("nan"))
    ('05:02:25', '25:10:00', '')
    """
    if t_s is None or t_s != t_s or t_s in (float("inf"), float("-inf")):
        return ""
    t = int(round(float(t_s)))
    return f"{t // 3600:02d}:{t // 60 % 60:02d}:{t % 60:02d}"


def hms(d_s, sign: bool = False) -> str:
    """A duration [s] → ``h:mm:ss`` for a person to read (258929 s → ``71:55:29``), rounded to the second;
    ``sign``: a leading + or − (−0:00:00 is written +0:00:00); ``–`` for no value (None, NaN).

    >>> hms(258929), hms(-83.4, sign=True), hms(59.6)
    ('71:55:29', '−0:01:23', '0:01:00')
    """
    if d_s is None or d_s != d_s or d_s in (float("inf"), float("-inf")):
        return "–"
    t = int(round(float(d_s)))
    s = ("−" if t < 0 else "+") if sign else ("−" if t < 0 else "")
    t = abs(t)
    return f"{s}{t // 3600}:{t // 60 % 60:02d}:{t % 60:02d}"


def percent(ratio, none: str = "–") -> str:
    """A ratio as whole percent, the way the pages write it (``100 %``, with the space).

    >>> percent(0.7), percent(1.0), percent(float("nan"))
    ('70 %', '100 %', '–')
    """
    t = fixed(None if ratio is None else 100.0 * float(ratio), 0, none=none)
    return t if t == none else f"{t} %"


def shown(x, nd: int = 1, sign: bool = False, none: str = "–") -> str:
    """``x`` as text with ``nd`` decimals (``sign``: a leading + or -), or with up to three more where ``nd``
    would show a non-zero value as zero: a margin of −0.03 s is flagged impossible and must not read 0.0
    (:func:`fixed` writes 0.0 for a value that is zero to the digits shown, where that is what a person
    wants); ``none`` for no value (None, NaN, inf).

    >>> shown(-0.032), shown(0.032, sign=True), shown(2.25, sign=True), shown(0.0), shown(-57.04), shown(-0.0004)
    ('-0.03', '+0.03', '+2.2', '0.0', '-57.0', '-0.0004')
    """
    if x is None or x != x or x in (float("inf"), float("-inf")):
        return none
    x = float(x)
    while x != 0.0 and round(x, nd) == 0.0 and nd < 4:
        nd += 1
    if round(x, nd) == 0.0:
        return f"{0.0:.{nd}f}"
    return f"{x:+.{nd}f}" if sign else f"{x:.{nd}f}"


def fixed(x, nd: int = 1, sign: bool = False, none: str = "–") -> str:
    """A number as fixed-point text for a person to read: ``nd`` decimals, ``sign`` a leading + or -; a value
    that rounds to zero is written ``0.0``, never ``-0.0`` (nor ``+0.0``: a sign there would say which side of
    zero it is, which the shown digits do not); ``none`` for no value (None, NaN, inf).

    >>> fixed(-0.032), fixed(-0.032, sign=True), fixed(2.25, 1, True), fixed(-57.04), fixed(float("nan"))
    ('0.0', '0.0', '+2.2', '-57.0', '–')
    """
    if x is None or x != x or x in (float("inf"), float("-inf")):
        return none
    t = f"{float(x):.{nd}f}"
    if float(t) == 0.0:
        return t.lstrip("-")
    return f"{float(x):+.{nd}f}" if sign else t
