"""graybox_native on a model whose configuration is not its velocities: the planar body,
its heading a unit complex number (nq = 4, nv = 3), answers in its widths and plans on the
tangent, turning the short way round."""

import subprocess

import numpy as np
import pytest

graybox_native = pytest.importorskip("graybox_native")
from graybox_native import GrayboxError  # noqa: E402


def test_a_model_of_nq_4_and_nv_3_answers_in_its_widths(graybox_bin, tmp_path):
    """The planar body (its heading a unit complex number): states of nq + nv = 7, v̇ of 3,
    Jacobians 6 wide in the tangent space, and a state of 6 refused naming x."""
    made = tmp_path / "body.gbx"
    subprocess.run([graybox_bin, "model", "--template", "planar_body", "--dt", "0.01",
                    "--out", str(made)], check=True, capture_output=True)
    model = graybox_native.load(str(made))
    info = model.info
    assert (info.nq, info.nv, info.n, info.m) == (4, 3, 3, 3), info
    assert info.joints == ["real", "real", "circle"], info
    th = 0.7
    x = np.array([0.1, -0.2, np.cos(th), np.sin(th), 0.5, 0.0, 1.0])
    x_next, accel = model.predict(x, np.ones(3), want_accel=True)
    assert x_next.shape == (7,) and accel.shape == (3,)
    # The heading stays on the unit circle (rounding of a few operations).
    assert abs(np.hypot(x_next[2], x_next[3]) - 1.0) < 1e-12
    A, B = model.linearize(x, np.ones(3))
    assert A.shape == (6, 6) and B.shape == (6, 3)
    with pytest.raises(GrayboxError) as e:
        model.predict(x[:6], np.ones(3))
    assert e.value.field == "x", e.value
    # A plan by either method: states of 7 on the circle, gains on the 6-wide tangent, and
    # across θ = ±π the heading turns the short way (never near θ = 0).
    start = np.array([0.0, 0.0, np.cos(-3.0), np.sin(-3.0), 0.0, 0.0, 0.0])
    goal = np.array([0.0, 0.0, np.cos(3.0), np.sin(3.0), 0.0, 0.0, 0.0])
    Q = np.diag([10.0] * 3 + [0.1] * 3)
    for method in ("ilqr", "dircol"):
        p = model.plan(start, goal, 100, Q, 1e-3 * np.eye(3), 100 * Q, method=method)
        assert p.x.shape == (101, 7) and p.K.shape == (100, 3, 6), method
        assert np.allclose(np.hypot(p.x[:, 2], p.x[:, 3]), 1.0, atol=1e-9), method
        assert np.abs(np.arctan2(p.x[:, 3], p.x[:, 2])).min() > 2.5, method
    with pytest.raises(GrayboxError) as e:
        model.plan(start, goal, 10, np.eye(7), np.eye(3), np.eye(7))
    assert e.value.field == "Q", e.value
