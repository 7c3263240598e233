"""The statistics of the Mitsuba side-by-side scripts (benches/exr_metrics.py): the verdicts of
benches/compare_xml.py rest on Student's t tail, written there without scipy."""

import importlib.util
import math

from conftest import ROOT


def exr_metrics():
    spec = importlib.util.spec_from_file_location("exr_metrics", ROOT / "benches" / "exr_metrics.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_student_t_tail_at_tabulated_quantiles():
    # two-sided 95% and 99% quantiles of Student's t (any statistics table)
    p = exr_metrics().student_t_two_sided
    for t, dof, alpha in [(12.7062, 1, 0.05), (2.262157, 9, 0.05), (2.042272, 30, 0.05),
                          (3.249836, 9, 0.01), (63.65674, 1, 0.01)]:
        assert math.isclose(p(t, dof), alpha, rel_tol=1e-5), (t, dof, p(t, dof))
        assert math.isclose(p(-t, dof), alpha, rel_tol=1e-5)


def test_student_t_tail_is_heavier_than_the_normal_and_tends_to_it():
    p = exr_metrics().student_t_two_sided
    normal = math.erfc(4.0 / math.sqrt(2.0))
    assert p(4.0, 7) > 20 * normal  # at a few runs the normal tail rejects far too often
    assert math.isclose(p(1.959964, 1e8), 0.05, rel_tol=1e-5)
    assert p(0.0, 3) == 1.0
