"""Friction maps (Eqs. A4-A7): closed-form radial integral vs brute quadrature, limits, k_f."""

import math

import numpy as np
import pytest
from scipy.special import ellipe

from bb_friction_ros import paper
from bb_friction_ros.contact import friction_maps as fm
from invariants import paper_approx

K = 0.2321463733660699   # b/a of Table 1 (conf 0.56)


def brute_force(vx, vy, w, k, n_theta=1500, n_r=300):
    """Plain 2-D quadrature of Eqs. (A4)-(A6) over the ellipse (polar about its centre)."""
    xr, wr = np.polynomial.legendre.leggauss(n_r)
    r, wr = (xr + 1) / 2, wr / 2
    th = (np.arange(n_theta) + 0.5) * 2 * np.pi / n_theta
    rr, tt = np.meshgrid(r, th)
    wgt = (3 / (2 * np.pi)) * np.sqrt(1 - rr ** 2) * rr * np.outer(
        np.full(n_theta, 2 * np.pi / n_theta), wr)
    x, y = rr * np.cos(tt), k * rr * np.sin(tt)
    sx, sy = vx - w * y, vy + w * x
    sn = np.hypot(sx, sy)
    tx, ty = -sx / sn, -sy / sn
    return np.array([np.sum(wgt * tx), np.sum(wgt * ty), np.sum(wgt * (x * ty - y * tx)),
                     np.sum(wgt * sn)])


@pytest.fixture(scope="module")
def line():
    return fm.FrictionMapLine(K)


@pytest.mark.parametrize("v", [(0, 0.1, 1), (0, -0.3, 1), (0.2, 0.1, 0.9), (0, 2, 1),
                               (0.5, -3, 0.4), (0, 1, 1e-3), (0, 0, 1), (1.0, 0.0, -0.7)])
def test_closed_form_matches_brute_quadrature(v):
    """Tolerance 2e-5: the brute force's own error (the slip direction jumps at the centre)."""
    d = np.array(v, float) / np.linalg.norm(v)
    ours = fm._rate_direction_integrals(*d, K)[:, 0]
    assert np.allclose(ours, brute_force(*d, K), atol=2e-5)


def test_eq11_pure_spin_moment(line):
    """Eq. (11): at c/a = 0, f = 0 and |M| = 3/8 mu F a Ellip(e)."""
    f, m, _ = line.evaluate(0.0)
    assert abs(f) < 1e-12
    assert abs(m) == pytest.approx(0.375 * ellipe(1 - K * K), rel=1e-8)


def test_eq12_pure_sliding_limits(line):
    """Eq. (12): c/a -> +-inf (w -> 0) gives |f| = mu F and M = 0, reached without singularity."""
    f, m, p = line.evaluate(np.array([-math.pi / 2, math.pi / 2]))
    assert np.allclose(np.abs(f), 1.0, atol=1e-9)
    assert np.allclose(m, 0.0, atol=1e-9)
    assert np.allclose(p, 1.0, atol=1e-9)


def test_fig5_kf_least_squares_slope(line):
    """k_f (paper, read off Fig. 5 over four conformities): ours 1.373 at conf 0.56.

    Tolerance and reason: ``paper.K_F``.  The tangent at 0 is 1.44.
    """
    ca_max = paper.FIGURES["kf_fit_max_c_over_a"]
    ca = np.linspace(-ca_max, ca_max, 201)
    f = line.evaluate(np.arctan(-ca))[0]
    assert np.sum(ca * f) / np.sum(ca * ca) == paper_approx(paper.K_F)
    tangent = -line.evaluate(0.0, derivative=True)[1][0]
    assert tangent == pytest.approx(1.44, abs=0.01)


def test_loss_identity_and_positivity(line):
    """p = -(f V + w m) exactly (power of the traction); loss is never negative."""
    u = np.linspace(-math.pi, math.pi, 721)
    f, m, p = line.exact(u)
    assert np.allclose(p, -(f * np.sin(u) + m * np.cos(u)), atol=1e-12)
    assert np.all(p >= 0)


def test_interpolation_accuracy_and_derivative(line):
    """Tabulated vs direct integration: < 1e-6; Hermite derivative vs central difference."""
    u = np.random.default_rng(3).uniform(-math.pi, math.pi, 500)
    assert np.abs(line.evaluate(u) - line.exact(u)).max() < 1e-6
    val, der = line.evaluate(u, derivative=True)
    h = 1e-6
    fd = (line.evaluate(u + h) - line.evaluate(u - h)) / (2 * h)
    assert np.abs(der - fd).max() < 1e-5


def test_sphere_map_reduces_to_line_map(line):
    """Slip along the rolling axis only (h = +-pi/2) is the linear-bearing map."""
    sph = fm.FrictionMapSphere(K)
    u = np.linspace(-math.pi + 0.01, math.pi - 0.01, 97)
    t, h = np.abs(u), np.where(u >= 0, math.pi / 2, -math.pi / 2)
    val, _, _ = sph.evaluate_angles(t, h)
    ref = line.evaluate(u)
    assert np.abs(val[1:] - ref).max() < 1e-4
    assert np.abs(val[0]).max() < 1e-6


def test_sphere_map_antisymmetry():
    """Reversing every velocity reverses force and moment and keeps the loss."""
    sph = fm.FrictionMapSphere(K)
    rng = np.random.default_rng(5)
    t, h = rng.uniform(0, math.pi, 50), rng.uniform(0, 2 * math.pi, 50)
    a = sph.exact(t, h)
    b = sph.exact(math.pi - t, h + math.pi)
    assert np.allclose(a[:3], -b[:3], atol=1e-12)
    assert np.allclose(a[3], b[3], atol=1e-12)


def test_table_cache_roundtrip(tmp_path, monkeypatch):
    """A table is built once, then read back identically from the disk cache."""
    monkeypatch.setenv("BB_FRICTION_CACHE", str(tmp_path))
    first = fm.FrictionMapLine(K, n_nodes=512)
    assert len(list(tmp_path.glob("line-*.npz"))) == 1
    second = fm.FrictionMapLine(K, n_nodes=512)
    u = np.linspace(-3, 3, 11)
    assert np.array_equal(first.evaluate(u), second.evaluate(u))


# --- a too-fine map is refused up front, a fine one is built in bounded memory

def test_too_fine_sphere_map_refused_by_name_with_the_figure():
    """4096 x 8192 nodes (inside the field ranges) would need tens of GiB: refused at load."""
    from bb_friction_ros.config import ConfigError
    from bb_friction_ros.model_file import load_ball_screw
    with pytest.raises(ConfigError, match=r"ball_screw\.solver\.map_polar_nodes x "
                       r"map_azimuth_nodes: .* needs about 3\d\.\d GiB .*"
                       r"ball_screw\.solver\.map_memory_limit_mib = 8192 MiB"):
        load_ball_screw(overrides={"solver": {"map_polar_nodes": 4096,
                                              "map_azimuth_nodes": 8192}})


def test_line_map_memory_limit_is_a_setting():
    from bb_friction_ros.config import ConfigError, load_linear_bearing
    cfg = load_linear_bearing(overrides={"map_nodes": 1 << 20})     # 2**20: ~0.5 GiB, allowed
    assert cfg.map_nodes == 1 << 20
    with pytest.raises(ConfigError, match=r"linear_bearing\.map_nodes: .* needs about "
                       r"5\d\d MiB .*linear_bearing\.map_memory_limit_mib = 100 MiB"):
        load_linear_bearing(overrides={"map_nodes": 1 << 20, "map_memory_limit_mib": 100})


def test_line_map_build_peak_within_its_estimate(tmp_path, monkeypatch):
    """
    Building a map in chunks keeps its peak within ``line_map_bytes``.

    Integrated all at once, the quadrature temporaries cost ~64 kB per node (1 GiB here,
    24 GB at 2**20 nodes); the estimate the config check uses must hold for the build.
    """
    import tracemalloc
    monkeypatch.setenv("BB_FRICTION_CACHE", str(tmp_path))
    monkeypatch.setattr(fm, "_IN_PROCESS", {})
    n = 16 * fm._BUILD_CHUNK
    tracemalloc.start()
    try:
        fm.FrictionMapLine(0.3, n_nodes=n)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak <= fm.line_map_bytes(n), (peak, fm.line_map_bytes(n))
