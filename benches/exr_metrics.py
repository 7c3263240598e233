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
