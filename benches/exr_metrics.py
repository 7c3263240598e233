"""What the two Mitsuba comparisons (compare_mitsuba.py, compare_xml.py) share: the CPU
seconds of finished child processes, an EXR's RGB as float64, and relMSE in pathspace's
definition."""

import resource

EPSILON = 1e-2  # measure::metrics::RELMSE_EPSILON


def child_cpu():
    """User + system CPU seconds of all finished child processes."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def read(path):
    """The RGB channels of an EXR as an (h, w, 3) float64 array."""
    import numpy as np
    import OpenEXR
    import Imath
    f = OpenEXR.InputFile(path)
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    ch = [np.frombuffer(f.channel(c, Imath.PixelType(Imath.PixelType.FLOAT)), dtype=np.float32)
          for c in "RGB"]
    return np.stack(ch, -1).reshape(h, w, 3).astype(np.float64)


def relmse(img, ref):
    """Mean of the squared error over the squared reference plus EPSILON, per pixel and channel."""
    return float((((img - ref) ** 2) / (ref ** 2 + EPSILON)).mean())


def _beta_fraction(a, b, x):
    """The continued fraction of the incomplete beta function (modified Lentz), for
    x < (a + 1) / (a + b + 2) where it converges fast."""
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 400):
        for num in (m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)),
                    -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1))):
            d = 1.0 + num * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + num / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < 1e-15:
            break
    return h


def incomplete_beta(a, b, x):
    """The regularized incomplete beta function I_x(a, b)."""
    import math
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    log_front = (math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
                 + a * math.log(x) + b * math.log1p(-x))
    if x < (a + 1.0) / (a + b + 2.0):
        return math.exp(log_front) * _beta_fraction(a, b, x) / a
    return 1.0 - math.exp(log_front) * _beta_fraction(b, a, 1.0 - x) / b


def student_t_two_sided(t, dof):
    """P(|T| >= |t|) for Student's t with `dof` degrees of freedom (real dof, as Welch's)."""
    return incomplete_beta(dof / 2.0, 0.5, dof / (dof + t * t))
