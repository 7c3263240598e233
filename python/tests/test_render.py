"""The variance of the mean against the spread of independent seeds, the progress callback,
Ctrl-C between passes (the partial result kept), diff and the convergence study."""

import math
import os
import signal
import threading

import numpy as np
import pytest

import pathspace
from conftest import FOG_BOX, SIZE, bits


def student_t_quantile(p: float, dof: int) -> float:
    """The p-quantile of Student's t with `dof` degrees of freedom (bisection on the CDF,
    by the regularized incomplete beta's continued fraction: no scipy needed)."""

    def betacf(a, b, x):
        qab, qap, qam = a + b, a + 1.0, a - 1.0
        c, d = 1.0, 1.0 - qab * x / qap
        d = 1.0 / d
        h = d
        for m in range(1, 300):
            m2 = 2 * m
            aa = m * (b - m) * x / ((qam + m2) * (a + m2))
            d = 1.0 / (1.0 + aa * d)
            c = 1.0 + aa / c
            h *= d * c
            aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
            d = 1.0 / (1.0 + aa * d)
            c = 1.0 + aa / c
            h *= d * c
        return h

    def ibeta(a, b, x):
        if x <= 0.0 or x >= 1.0:
            return max(0.0, min(1.0, x))
        lb = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
        front = math.exp(lb + a * math.log(x) + b * math.log(1.0 - x))
        if x < (a + 1.0) / (a + b + 2.0):
            return front * betacf(a, b, x) / a
        return 1.0 - front * betacf(b, a, 1.0 - x) / b

    def cdf(t):
        x = dof / (dof + t * t)
        tail = 0.5 * ibeta(dof / 2.0, 0.5, x)
        return 1.0 - tail if t > 0 else tail

    lo, hi = 0.0, 100.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if cdf(mid) < p else (lo, mid)
    return 0.5 * (lo + hi)


def test_student_t_quantile():
    assert abs(student_t_quantile(0.975, 10) - 2.228) < 1e-3
    assert abs(student_t_quantile(0.995, 100) - 2.626) < 1e-3


def test_variance_of_the_mean_is_the_spread_of_seeds():
    """Per pixel and channel, s^2 is the sample variance of 16 images of independent seeds
    and v the mean reported variance of the mean of 8 other seeds: independent estimates of
    the same variance, so w (s^2 - v) has mean 0 for any weight w independent of both (here
    from 4 more seeds' variances, which evens out the pixels; black pixels left out). Summed
    over the channels, one value per pixel; the pixels (independent streams) give the mean's
    standard error: a two-sided Student-t test at 1e-3."""
    scene = pathspace.load_file(FOG_BOX, resolution=(16, 12))

    def variances(seeds):
        rs = [scene.render(integrator="path", spp=64, seed=s, threads=2) for s in seeds]
        return np.stack([r.variance for r in rs]).astype(np.float64).reshape(len(rs), -1, 3)

    images = np.stack([scene.render(spp=64, seed=s, threads=2).image
                       for s in range(100, 116)]).astype(np.float64).reshape(16, -1, 3)
    spread = images.var(axis=0, ddof=1)
    reported = variances(range(200, 208)).mean(axis=0)
    v = variances(range(300, 304)).mean(axis=0)
    lit = (v > 0).all(axis=1)
    w = 1.0 / (v + np.median(v[lit], axis=0))
    t = student_t_quantile(1.0 - 1e-3 / 2, lit.sum() - 1)

    def t_ratio(reported):
        d = ((spread - reported) * w)[lit].sum(axis=1)
        return d.mean() / (d.std(ddof=1) / math.sqrt(d.shape[0]))

    assert abs(t_ratio(reported)) <= t, (t_ratio(reported), t)
    # the test has power: the variance of one sample (64x the mean's) is refused
    assert abs(t_ratio(64 * reported)) > t


def test_progress_is_called_after_every_pass():
    calls = []
    scene = pathspace.load_file(FOG_BOX, resolution=SIZE)
    scene.render(spp=10, seed=1, threads=2, progress=lambda done, target: calls.append(
        (done, target)))
    assert calls == [(4, 10), (8, 10), (10, 10)]


def test_an_interrupt_between_passes_keeps_the_samples():
    scene = pathspace.load_file(FOG_BOX, resolution=SIZE)

    def ctrl_c_after_the_first_pass(done, target):
        if done == 4:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt) as e:
        scene.render(spp=64, seed=9, threads=2, progress=ctrl_c_after_the_first_pass)
    partial = e.value.result
    assert isinstance(e.value, pathspace.Interrupted)
    assert partial.spp == 4 and not partial.complete
    # the partial result is the first pass's samples: a render of 4 spp bit for bit
    alone = scene.render(spp=4, seed=9, threads=2)
    assert np.array_equal(bits(partial.image), bits(alone.image))
    assert np.array_equal(bits(partial.variance), bits(alone.variance))


def test_a_real_sigint_stops_after_the_pass_in_flight():
    """SIGINT from another thread while the passes run (the GIL released): the render ends
    after the pass in flight and raises KeyboardInterrupt with the samples done."""
    scene = pathspace.load_file(FOG_BOX, resolution=(64, 48))
    started = threading.Event()

    def progress(done, target):
        started.set()

    def send():
        started.wait()
        os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=send, daemon=True).start()
    with pytest.raises(pathspace.Interrupted) as e:
        scene.render(spp=2048, seed=1, threads=2, progress=progress)
    r = e.value.result
    assert 4 <= r.spp < 2048 and r.spp % 4 == 0
    assert np.isfinite(r.image).all()
    assert r.provenance["complete"] == "false"


def test_diff_and_convergence():
    scene = pathspace.load_file(FOG_BOX, resolution=SIZE)
    a = scene.render(spp=4, seed=1, threads=2)
    b = scene.render(spp=4, seed=2, threads=2)
    same = pathspace.diff(a, a)
    assert same["rmse"] == 0.0 and same["max_f32_steps"] == 0
    m = pathspace.diff(a, b)
    x, y = a.image.astype(np.float64), b.image.astype(np.float64)
    assert math.isclose(m["rmse"], math.sqrt(((x - y) ** 2).mean()), rel_tol=1e-9)
    assert math.isclose(m["relmse"], ((x - y) ** 2 / (y ** 2 + 1e-2)).mean(), rel_tol=1e-9)
    reference = scene.render(spp=64, seed=3, threads=2)
    rows = pathspace.converge(scene, reference, ["path", "bdpt"], budget=0.2, checkpoints=2)
    assert {r["integrator"] for r in rows} == {"path", "bdpt"}
    assert all(set(r) == {"integrator", "run", "checkpoint", "seconds", "samples", "rmse",
                          "relmse", "efficiency"} for r in rows)
    assert all(r["relmse"] > 0 and r["samples"] > 0 for r in rows)
