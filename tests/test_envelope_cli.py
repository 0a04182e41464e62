"""``allsky analyze --envelope``: the printed and written figures, and the 3-D figure.

Truth comes from :mod:`allsky.vehicle.envelopes` (checked there against Qhull
and closed forms): the printed and JSON figures must be those of
:func:`allsky.vehicle.envelopes.envelope_summary`, and each drawn facet must
lie on its plane, ``n . v = h(n)`` with ``h`` the zonotope's support function
``h(n) = sum_i L_i |n . g_i|``. Closed forms for the default pyramid
(``tan^2 beta = 2``, docs/envelopes.md): every facet at ``2 tau sqrt(2/3)``;
the dither's peak torque is ``J A w^2`` with ``w = 2 pi / T``.
"""

import json
import math
import re

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from mpl_toolkits.mplot3d import proj3d
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from allsky.apps import analyze as analyze_app
from allsky.apps.cli import _parser, main
from allsky.hardware.jets import make_params
from allsky.vehicle.envelopes import envelope_summary, make_envelope, pyramid_axes

NUMBER = r"[-+]?\d+(?:\.\d*)?(?:e[-+]?\d+)?"


def default_jets_n_m(cfg):
    return make_params(cfg.jets.thrust_n, cfg.jets.moment_arm_m, cfg.jets.isp_s).torque_n_m


@pytest.fixture(scope="module")
def default_envelopes(default_cfg):
    return analyze_app.envelope_analysis(default_jets_n_m(default_cfg))


def _strict(text):
    def refuse(c):
        raise ValueError(f"non-standard JSON constant {c}")
    return json.loads(text, parse_constant=refuse)


def _row(out, label):
    """The numbers of the printed row starting with ``label``."""
    line = next(x for x in out.splitlines() if x.strip().startswith(label))
    return [float(v) for v in re.findall(NUMBER, line[len(line) - len(line.lstrip())
                                                       + len(label):])]


# -- the defaults ----------------------------------------------------------------------------

def test_default_pyramid_puts_every_facet_at_the_same_distance():
    tau = analyze_app.DEFAULT_WHEEL_TORQUE_N_M
    env = make_envelope(pyramid_axes(analyze_app.DEFAULT_PYRAMID_BETA_DEG), tau)
    assert math.tan(math.radians(analyze_app.DEFAULT_PYRAMID_BETA_DEG)) ** 2 == \
        pytest.approx(2.0)
    assert np.allclose(env.offsets, 2.0 * tau * math.sqrt(2.0 / 3.0), rtol=1e-12)
    # ... which makes its inscribed radius, with or without a failure, the largest.
    for beta in (analyze_app.DEFAULT_PYRAMID_BETA_DEG - 0.5,
                 analyze_app.DEFAULT_PYRAMID_BETA_DEG + 0.5):
        other = make_envelope(pyramid_axes(beta), tau)
        assert other.min_radius < env.min_radius
        assert other.without(0).min_radius < env.without(0).min_radius


def test_default_wheels_meet_what_the_help_says(default_envelopes):
    # 0.1 N m: after the worst failure the inscribed radius is 0.816 tau, > 3 times the
    # dither's peak torque J A w^2 = 0.0241 N m. 50 N m s: after the worst failure the
    # inscribed momentum radius holds 16000 kg m^2 at 0.1 deg/s (27.9 N m s).
    d = analyze_app.DITHER_EXAMPLE
    peak = d["inertia_kg_m2"] * d["amplitude_rad"] * (2.0 * math.pi / d["period_s"]) ** 2
    assert peak == pytest.approx(0.0241, abs=5e-5)
    failed = default_envelopes["wheels"]["one_failed"]
    assert failed["torque"]["min_radius_n_m"] / peak > 3.0
    assert failed["momentum"]["min_radius_n_m_s"] >= d["inertia_kg_m2"] * math.radians(0.1)
    help_text = _parser()._subparsers._group_actions[0].choices["analyze"].format_help()
    help_text = " ".join(help_text.split())
    assert f"default {analyze_app.DEFAULT_WHEEL_TORQUE_N_M:g}" in help_text
    assert f"default {analyze_app.DEFAULT_WHEEL_MOMENTUM_N_M_S:g}" in help_text
    assert f"= {analyze_app.DEFAULT_PYRAMID_BETA_DEG:.2f}" in help_text


# -- the library function ----------------------------------------------------------------------

def test_envelope_analysis_is_envelope_summary_plus_the_dither_check(default_cfg,
                                                                     default_envelopes):
    jets = default_jets_n_m(default_cfg)
    beta = analyze_app.DEFAULT_PYRAMID_BETA_DEG
    truth = envelope_summary(pyramid_axes(beta), analyze_app.DEFAULT_WHEEL_TORQUE_N_M,
                             analyze_app.DEFAULT_WHEEL_MOMENTUM_N_M_S, jets)
    assert {k: default_envelopes[k] for k in truth} == truth
    assert set(default_envelopes) == {"wheels", "jets", "wheel_array", "dither_check"}


def test_dither_margins_are_reach_over_peak_torque(default_cfg, default_envelopes):
    dc = default_envelopes["dither_check"]
    w = 2.0 * math.pi / dc["period_s"]
    peak = dc["inertia_kg_m2"] * dc["amplitude_rad"] * w ** 2
    assert dc["peak_torque_n_m"] == pytest.approx(peak, rel=1e-12)
    # The profile samples fall on the peaks (64 per period), so the margin along each axis
    # is the reach along it over J A w^2.
    wheels = default_envelopes["wheels"]
    for key, reach in (("wheels", wheels["torque"]["max_n_m"]),
                       ("one_failed", wheels["one_failed"]["torque"]["max_n_m"]),
                       ("jets", default_envelopes["jets"]["torque"]["max_n_m"])):
        assert dc[key]["margin_per_axis"] == pytest.approx(np.array(reach) / peak, rel=1e-9)
        assert dc[key]["margin"] == min(dc[key]["margin_per_axis"])
        assert dc[key]["inside"] == (dc[key]["margin"] >= 1.0)
    # Closed form for the pyramid: pitch reach 2 tau sin(beta) (docs/envelopes.md).
    tau, beta = analyze_app.DEFAULT_WHEEL_TORQUE_N_M, analyze_app.DEFAULT_PYRAMID_BETA_DEG
    assert dc["wheels"]["margin_per_axis"][1] == pytest.approx(
        2.0 * tau * math.sin(math.radians(beta)) / peak, rel=1e-12)


def test_a_small_wheel_fails_the_dither_check(default_cfg):
    r = analyze_app.envelope_analysis(default_jets_n_m(default_cfg), 60.0, 0.005, 4.0)
    # Pitch reach 2 tau sin 60 = 0.00866 N m < 0.0241 N m.
    assert not r["dither_check"]["wheels"]["inside"]
    assert r["dither_check"]["wheels"]["margin"] == pytest.approx(
        2.0 * 0.005 * math.sin(math.radians(60.0)) / r["dither_check"]["peak_torque_n_m"])


# -- the figure: one polygon per facet, each on its plane ------------------------------------

@pytest.mark.parametrize("axes, limits", [
    (pyramid_axes(54.7356103172453), 0.1),
    (pyramid_axes(30.0), [0.1, 0.2, 0.3, 0.4]),
    (pyramid_axes(60.0)[1:], 0.05),  # one wheel failed
    # A coplanar triple (x, y and their bisector) gives hexagonal facets.
    (np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [math.sqrt(0.5), math.sqrt(0.5), 0.0],
               [0.0, 0.0, 1.0]]), [0.1, 0.2, 0.3, 0.4]),
    (np.eye(3)[:2], 1.0),  # flat: two axes in the x-y plane
])
def test_facet_polygons_lie_on_their_planes_and_are_faces(axes, limits):
    env = make_envelope(axes, limits)
    polygons = analyze_app.facet_polygons(env)
    assert len(polygons) == len(env.normals)
    rng = np.random.default_rng(1)
    probes = rng.normal(size=(200, 3))
    for n, h, poly in zip(env.normals, env.offsets, polygons, strict=True):
        # On the plane: n . v = h(n), the support function.
        assert np.allclose(poly @ n, env.support(n), atol=1e-12)
        assert np.allclose(poly @ n, h, atol=1e-12)
        # Inside the envelope: d . v <= h(d) for every direction d.
        assert np.all(poly @ probes.T <= env.support(probes) + 1e-12)
        if env.rank == 3:
            # A face, not a segment: its area is that of the facet, sum over in-plane
            # pairs of 4 L_i L_j |(g_i x g_j) . n| (a zonotope's facet is a 2-D zonotope).
            idx = env.facet_axes[list(env.normals.tolist()).index(n.tolist())]
            area = sum(4.0 * env.limits[i] * env.limits[j]
                       * abs(np.cross(env.axes[i], env.axes[j]) @ n)
                       for a, i in enumerate(idx) for j in idx[a + 1:])
            shoelace = 0.5 * abs(sum(np.cross(poly[k], poly[(k + 1) % len(poly)])
                                     for k in range(len(poly))) @ n)
            assert shoelace == pytest.approx(area, rel=1e-9)
            # Counter-clockwise seen from outside.
            assert sum(np.cross(poly[k], poly[(k + 1) % len(poly)])
                       for k in range(len(poly))) @ n > 0


def test_figure_draws_one_polygon_per_facet_on_its_plane(default_envelopes):
    fig = analyze_app.envelope_figure(default_envelopes)
    FigureCanvasAgg(fig).draw()  # projects the 3-D polygons onto the panels
    arr = default_envelopes["wheel_array"]
    full = make_envelope(np.array(arr["axes"]), arr["torque_max_n_m"])
    failed = full.without(default_envelopes["wheels"]["one_failed"]["wheel"])
    panels = [ax for ax in fig.axes if ax.name == "3d"]
    assert len(panels) == 2
    for ax, env in zip(panels, (full, failed), strict=True):
        facets = [c for c in ax.collections if isinstance(c, Poly3DCollection)]
        assert len(facets) == 1
        drawn = facets[0].get_paths()
        assert len(drawn) == len(env.normals)  # one polygon per facet
        # Each drawn polygon is the projection of one facet polygon (whose corners lie
        # on the facet's plane: test_facet_polygons_lie_on_their_planes_and_are_faces);
        # the collection draws them back to front, so compare as sets.
        want = set()
        for poly in analyze_app.facet_polygons(env):
            x, y, _ = proj3d.proj_transform(*poly.T, ax.get_proj())
            want.add(tuple(sorted(zip(np.round(x, 9), np.round(y, 9)))))
        got = {tuple(sorted(map(tuple, np.round(p.vertices[:len(p.vertices) - 1], 9))))
               for p in drawn}
        assert got == want
    assert analyze_app.envelope_figure(default_envelopes, show_failure=False).axes[0].name \
        == "3d"


# -- the command -----------------------------------------------------------------------------

def test_command_prints_the_summary_figures(tmp_path, capsys, default_envelopes):
    assert main(["analyze", "--envelope"]) == 0
    out = capsys.readouterr().out
    w, jets = default_envelopes["wheels"], default_envelopes["jets"]
    failed = w["one_failed"]["wheel"]

    def figures(reach, unit):
        return [reach[f"min_radius_{unit}"], *reach[f"max_{unit}"]]

    for label, reach, unit in (("wheels, torque [N m]", w["torque"], "n_m"),
                               ("wheels, momentum [N m s]", w["momentum"], "n_m_s"),
                               (f"wheel {failed} failed, torque", w["one_failed"]["torque"],
                                "n_m"),
                               (f"wheel {failed} failed, momentum",
                                w["one_failed"]["momentum"], "n_m_s"),
                               ("jets 39-41, torque [N m]", jets["torque"], "n_m")):
        assert _row(out, label) == pytest.approx(figures(reach, unit), rel=5e-4)
    dc = default_envelopes["dither_check"]
    assert f"J A w^2 = {dc['peak_torque_n_m']:.4g} N m" in out
    for label, key in (("wheels", "wheels"), (f"wheel {failed} failed", "one_failed"),
                       ("jets 39-41", "jets")):
        line = [x for x in out.splitlines() if x.strip().startswith(label)][-1]
        assert line.rstrip().endswith("yes")
        assert [float(v) for v in re.findall(NUMBER, line[len(label) + 2:])] == \
            pytest.approx(dc[key]["margin_per_axis"], rel=5e-4)
    assert "Loop margins" not in out  # the loop tables are not computed


def test_command_json_layout_is_the_contract(tmp_path, capsys, default_envelopes):
    js = tmp_path / "env.json"
    assert main(["analyze", "--envelope", "--json", str(js)]) == 0
    assert f"wrote {js}" in capsys.readouterr().out
    data = _strict(js.read_text())
    reach_t = {"min_radius_n_m", "max_n_m"}
    reach_h = {"min_radius_n_m_s", "max_n_m_s"}
    assert set(data) == {"wheels", "jets", "wheel_array", "dither_check"}
    assert set(data["wheels"]) == {"torque", "momentum", "one_failed"}
    assert set(data["wheels"]["torque"]) == reach_t
    assert set(data["wheels"]["momentum"]) == reach_h
    assert set(data["wheels"]["one_failed"]) == {"wheel", "torque", "momentum"}
    assert set(data["wheels"]["one_failed"]["torque"]) == reach_t
    assert set(data["wheels"]["one_failed"]["momentum"]) == reach_h
    assert set(data["jets"]) == {"torque"} and set(data["jets"]["torque"]) == reach_t
    for reach in (data["wheels"]["torque"], data["jets"]["torque"]):
        assert len(reach["max_n_m"]) == 3
    assert data == json.loads(json.dumps(default_envelopes))


def test_command_json_to_stdout_and_plot(tmp_path, capsys, default_envelopes):
    png = tmp_path / "env.png"
    assert main(["analyze", "--envelope", "--json", "-", "--plot", str(png),
                 "--wheel-torque", "0.2", "--wheel-momentum", "20", "--wheel-beta", "60"]) == 0
    data = _strict(capsys.readouterr().out)
    assert data["wheel_array"]["torque_max_n_m"] == 0.2
    assert data["wheel_array"]["beta_deg"] == 60.0
    # Pyramid closed form (docs/envelopes.md): reach along x 4 tau cos(beta).
    assert data["wheels"]["torque"]["max_n_m"][0] == pytest.approx(4 * 0.2 * 0.5, rel=1e-12)
    assert data["wheels"]["momentum"]["max_n_m_s"][0] == pytest.approx(4 * 20.0 * 0.5,
                                                                       rel=1e-12)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_command_follows_the_scenario_jets(capsys, default_cfg):
    assert main(["analyze", "--envelope", "--json", "-",
                 "--set", "jets.thrust_n=[0.5, 0.5, 0.5]"]) == 0
    data = _strict(capsys.readouterr().out)
    # A couple gives 2 F r.
    assert data["jets"]["torque"]["max_n_m"] == pytest.approx(
        2.0 * 0.5 * np.asarray(default_cfg.jets.moment_arm_m), rel=1e-15)


@pytest.mark.parametrize("argv, says", [
    (["--envelope", "--wheel-torque", "-0.1"], "--wheel-torque"),
    (["--envelope", "--wheel-momentum", "0"], "--wheel-momentum"),
    (["--envelope", "--wheel-beta", "90"], "--wheel-beta"),
    (["--envelope", "--wheel-torque", "nan"], "--wheel-torque"),
    (["--wheel-torque", "0.2"], "--wheel-torque: only with --envelope"),
    (["--envelope", "--plot", "env.txt"], "--plot"),
])
def test_bad_options_exit_2_with_one_line(argv, says, capsys):
    assert main(["analyze", *argv]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("allsky: error:") and says in lines[0]
