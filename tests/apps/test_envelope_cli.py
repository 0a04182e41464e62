"""``allsky analyze --envelope``: the printed and written figures, and the 3-D figure.

The array analysed is the scenario's ``[wheels]``. Truth comes from
:mod:`allsky.vehicle.envelopes` (checked there against Qhull and closed
forms): the printed and JSON figures must be those of
:func:`allsky.vehicle.envelopes.envelope_summary` for that array, and each
drawn facet must lie on its plane, ``n . v = h(n)`` with ``h`` the zonotope's
support function ``h(n) = sum_i L_i |n . g_i|``. For an array that is no
pyramid the inscribed radius is checked against Qhull's hull of the 2^n
corners ``sum_i c_i L_i g_i``, ``c_i = +-1``. Closed forms for the default
pyramid (``tan^2 beta = 2``, docs/envelopes.md): every facet at
``2 tau sqrt(2/3)``; the dither's peak torque is ``J A w^2`` with
``w = 2 pi / T``.
"""

import itertools
import json
import math
import re

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from mpl_toolkits.mplot3d import proj3d
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from scipy.spatial import ConvexHull

from allsky.apps import analyze as analyze_app
from allsky.apps.cli import _parser, main
from allsky.hardware.jets import make_params
from allsky.studies.envelope_check import DITHER_EXAMPLE, envelope_analysis, scenario_envelopes
from allsky.vehicle.envelopes import envelope_summary, make_envelope, pyramid_axes

NUMBER = r"[-+]?\d+(?:\.\d*)?(?:e[-+]?\d+)?"
#: tan^2 beta = 2: the pyramid whose twelve facets are equally far (docs/envelopes.md).
BALANCED_BETA_DEG = math.degrees(math.atan(math.sqrt(2.0)))
#: Three orthogonal wheels and one along (1, 1, 1)/sqrt 3, each with its own limits.
SKEW_AXES = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0],
             [1 / math.sqrt(3.0), 1 / math.sqrt(3.0), 1 / math.sqrt(3.0)]]
SKEW_TORQUE_N_M = [0.2, 0.3, 0.4, 0.5]
SKEW_MOMENTUM_N_M_S = [10.0, 12.0, 14.0, 30.0]
SKEW_SETS = ["--set", f"wheels.axes={SKEW_AXES}",
             "--set", f"wheels.max_torque_n_m={SKEW_TORQUE_N_M}",
             "--set", f"wheels.max_momentum_n_m_s={SKEW_MOMENTUM_N_M_S}"]


def default_jets_n_m(cfg):
    return make_params(cfg.jets.thrust_n, cfg.jets.moment_arm_m, cfg.jets.isp_s).torque_n_m


@pytest.fixture(scope="module")
def default_envelopes(default_cfg):
    return scenario_envelopes(default_cfg)


def hull_min_radius(axes, limits):
    """Inscribed radius of Qhull's hull of the 2^n corners (the brute force)."""
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=len(limits))))
    hull = ConvexHull(signs @ (np.asarray(limits)[:, None] * np.asarray(axes)))
    return float(np.min(-hull.equations[:, 3]))  # n . x + d <= 0 inside, |n| = 1


def hull_max_along_body_axes(axes, limits):
    """Largest reach along x, y, z of the same hull."""
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=len(limits))))
    eq = ConvexHull(signs @ (np.asarray(limits)[:, None] * np.asarray(axes))).equations
    return [float(np.min(-eq[eq[:, k] > 1e-12, 3] / eq[eq[:, k] > 1e-12, k]))
            for k in range(3)]


def _strict(text):
    def refuse(c):
        raise ValueError(f"non-standard JSON constant {c}")
    return json.loads(text, parse_constant=refuse)


def _row(out, label):
    """The numbers of the printed row starting with ``label``."""
    line = next(x for x in out.splitlines() if x.strip().startswith(label))
    return [float(v) for v in re.findall(NUMBER, line[len(line) - len(line.lstrip())
                                                       + len(label):])]


# -- the array: the scenario's [wheels] ---------------------------------------------------

def test_default_scenario_array_is_the_balanced_pyramid(default_cfg, default_envelopes):
    # default.toml: four wheels at atan(sqrt 2) from +x, so every facet at 2 tau sqrt(2/3).
    arr = default_envelopes["wheel_array"]
    tau = default_cfg.wheels.max_torque_n_m
    assert np.allclose(arr["axes"], pyramid_axes(BALANCED_BETA_DEG), rtol=0, atol=1e-15)
    assert arr["torque_max_n_m"] == [tau] * 4
    assert arr["momentum_max_n_m_s"] == [default_cfg.wheels.max_momentum_n_m_s] * 4
    assert arr["beta_deg"] is None
    assert arr["source"] == {"axes": "scenario", "torque_max_n_m": "scenario",
                             "momentum_max_n_m_s": "scenario"}
    env = make_envelope(arr["axes"], tau)
    assert np.allclose(env.offsets, 2.0 * tau * math.sqrt(2.0 / 3.0), rtol=1e-12)
    # ... which makes its inscribed radius, with or without a failure, the largest.
    for beta in (BALANCED_BETA_DEG - 0.5, BALANCED_BETA_DEG + 0.5):
        other = make_envelope(pyramid_axes(beta), tau)
        assert other.min_radius < env.min_radius
        assert other.without(0).min_radius < env.without(0).min_radius


def test_help_names_the_scenario_keys_the_options_replace():
    help_text = _parser()._subparsers._group_actions[0].choices["analyze"].format_help()
    help_text = " ".join(help_text.split())
    for key in ("wheels.axes", "wheels.max_torque_n_m", "wheels.max_momentum_n_m_s"):
        assert f"the scenario's {key}" in help_text
    assert "not the emulated one" in help_text


# -- the library function ----------------------------------------------------------------------

def test_envelope_analysis_is_envelope_summary_plus_the_dither_check(default_cfg,
                                                                     default_envelopes):
    w = default_cfg.wheels
    truth = envelope_summary(w.axes, w.max_torque_n_m, w.max_momentum_n_m_s,
                             default_jets_n_m(default_cfg))
    added = {"pseudo_inverse", "allocation"}
    assert {k: default_envelopes[k] for k in truth if k != "wheels"} == \
        {k: v for k, v in truth.items() if k != "wheels"}
    assert {k: v for k, v in default_envelopes["wheels"].items() if k not in added} == \
        truth["wheels"]
    assert set(default_envelopes) == {"wheels", "jets", "wheel_array", "dither_check"}
    # What the minimum norm reaches on the equal-facet pyramid: 4L/3 against the
    # zonotope's 2L sqrt(2/3) in torque (L = 0.5 N m), the same shape in momentum (20 N m s).
    pinv = default_envelopes["wheels"]["pseudo_inverse"]
    assert pinv["torque"]["min_radius_n_m"] == pytest.approx(4 * 0.5 / 3, rel=1e-12)
    assert pinv["momentum"]["min_radius_n_m_s"] == pytest.approx(4 * 20.0 / 3, rel=1e-12)
    assert pinv["torque"]["max_n_m"] == pytest.approx(truth["wheels"]["torque"]["max_n_m"],
                                                      rel=1e-12)
    assert default_envelopes["wheels"]["allocation"] == "pseudo_inverse"
    assert default_envelopes["dither_check"]["emulated_inertia_kg_m2"] == \
        [default_cfg.vehicle.inertia_kg_m2[k][k] for k in range(3)]


def test_dither_margins_are_reach_over_peak_torque(default_cfg, default_envelopes):
    dc = default_envelopes["dither_check"]
    assert {k: dc[k] for k in DITHER_EXAMPLE} == dict(DITHER_EXAMPLE)
    w = 2.0 * math.pi / dc["period_s"]
    peak = dc["inertia_kg_m2"] * dc["amplitude_rad"] * w ** 2
    assert dc["peak_torque_n_m"] == pytest.approx(peak, rel=1e-12)
    assert peak == pytest.approx(0.0241, abs=5e-5)
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
    tau = default_cfg.wheels.max_torque_n_m
    assert dc["wheels"]["margin_per_axis"][1] == pytest.approx(
        2.0 * tau * math.sin(math.radians(BALANCED_BETA_DEG)) / peak, rel=1e-12)


def test_a_small_wheel_fails_the_dither_check(default_cfg):
    r = envelope_analysis(default_jets_n_m(default_cfg), pyramid_axes(60.0), 0.005, 4.0)
    # Pitch reach 2 tau sin 60 = 0.00866 N m < 0.0241 N m.
    assert not r["dither_check"]["wheels"]["inside"]
    assert r["dither_check"]["wheels"]["margin"] == pytest.approx(
        2.0 * 0.005 * math.sin(math.radians(60.0)) / r["dither_check"]["peak_torque_n_m"])


def test_options_replace_parts_of_the_scenario_array(default_cfg):
    four = default_cfg.wheels.axes
    r = scenario_envelopes(default_cfg, torque_max_n_m=0.2)
    arr = r["wheel_array"]
    assert arr["axes"] == [list(g) for g in four]
    assert arr["torque_max_n_m"] == [0.2] * 4
    assert arr["source"] == {"axes": "scenario", "torque_max_n_m": "given",
                             "momentum_max_n_m_s": "scenario"}
    # A pyramid keeps four per-wheel limits, wheel by wheel.
    from allsky.config import load_scenario

    cfg = load_scenario(overrides=["wheels.max_torque_n_m=[0.1, 0.2, 0.3, 0.4]"])
    arr = scenario_envelopes(cfg, beta_deg=30.0)["wheel_array"]
    assert arr["axes"] == pyramid_axes(30.0).tolist() and arr["beta_deg"] == 30.0
    assert arr["torque_max_n_m"] == [0.1, 0.2, 0.3, 0.4]
    assert arr["source"]["axes"] == "given"


# -- a scenario whose array is no pyramid ------------------------------------------------------

def test_skew_array_from_the_scenario_matches_the_brute_force_hull(capsys):
    assert main(["analyze", "--envelope", "--json", "-", *SKEW_SETS]) == 0
    data = _strict(capsys.readouterr().out)
    arr = data["wheel_array"]
    assert np.allclose(arr["axes"], SKEW_AXES, rtol=0, atol=1e-15)
    assert arr["torque_max_n_m"] == SKEW_TORQUE_N_M
    assert arr["momentum_max_n_m_s"] == SKEW_MOMENTUM_N_M_S
    w = data["wheels"]
    assert w["torque"]["min_radius_n_m"] == pytest.approx(
        hull_min_radius(SKEW_AXES, SKEW_TORQUE_N_M), rel=1e-9)
    assert w["momentum"]["min_radius_n_m_s"] == pytest.approx(
        hull_min_radius(SKEW_AXES, SKEW_MOMENTUM_N_M_S), rel=1e-9)
    assert w["torque"]["max_n_m"] == pytest.approx(
        hull_max_along_body_axes(SKEW_AXES, SKEW_TORQUE_N_M), rel=1e-9)
    # The worst single failure: the one leaving the smallest hull's inscribed radius.
    radii = [hull_min_radius(np.delete(SKEW_AXES, i, axis=0), np.delete(SKEW_TORQUE_N_M, i))
             for i in range(4)]
    failed = w["one_failed"]
    assert failed["wheel"] == int(np.argmin(radii))
    assert failed["torque"]["min_radius_n_m"] == pytest.approx(min(radii), rel=1e-9)
    # The dither example's margin in this array: the reach along each axis / J A w^2.
    dc = data["dither_check"]
    assert dc["wheels"]["margin_per_axis"] == pytest.approx(
        np.array(w["torque"]["max_n_m"]) / dc["peak_torque_n_m"], rel=1e-9)


def test_figure_draws_any_number_of_wheels(default_cfg):
    from allsky.config import load_scenario

    five = [*SKEW_AXES, [0.0, math.sqrt(0.5), -math.sqrt(0.5)]]
    cfg = load_scenario(overrides=[f"wheels.axes={five}",
                                   "wheels.max_torque_n_m=[0.2, 0.3, 0.4, 0.5, 0.25]"])
    result = scenario_envelopes(cfg)
    fig = analyze_app.envelope_figure(result)
    FigureCanvasAgg(fig).draw()
    arr = result["wheel_array"]
    full = make_envelope(arr["axes"], arr["torque_max_n_m"])
    panels = [ax for ax in fig.axes if ax.name == "3d"]
    failed = full.without(result["wheels"]["one_failed"]["wheel"])
    for ax, env, spokes in zip(panels, (full, failed), (5, 4), strict=True):
        facets = [c for c in ax.collections if isinstance(c, Poly3DCollection)]
        assert len(facets[0].get_paths()) == len(env.normals)
        assert sum(t.get_text().startswith(" wheel ") for t in ax.texts) == spokes
    assert "5 wheels" in fig.texts[0].get_text()


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
    # The array and where it came from; the example vehicle is not the emulated one.
    assert "Reaction wheels: 4 wheels, the scenario's [wheels]" in out
    assert ("axes: wheels.axes; torque limits: wheels.max_torque_n_m; momentum limits: "
            "wheels.max_momentum_n_m_s") in out
    assert "example vehicle (not the emulated one, whose inertia is 100, 650, 680" in out


def test_command_json_layout_is_the_contract(tmp_path, capsys, default_envelopes):
    js = tmp_path / "env.json"
    assert main(["analyze", "--envelope", "--json", str(js)]) == 0
    assert f"wrote {js}" in capsys.readouterr().out
    data = _strict(js.read_text())
    reach_t = {"min_radius_n_m", "max_n_m"}
    reach_h = {"min_radius_n_m_s", "max_n_m_s"}
    assert set(data) == {"wheels", "jets", "wheel_array", "dither_check"}
    assert set(data["wheels"]) == {"torque", "momentum", "one_failed", "pseudo_inverse",
                                   "allocation"}
    assert set(data["wheels"]["pseudo_inverse"]["torque"]) == reach_t
    assert set(data["wheels"]["pseudo_inverse"]["momentum"]) == reach_h
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
    assert data["wheel_array"]["torque_max_n_m"] == [0.2] * 4
    assert data["wheel_array"]["momentum_max_n_m_s"] == [20.0] * 4
    assert data["wheel_array"]["beta_deg"] == 60.0
    assert set(data["wheel_array"]["source"].values()) == {"given"}
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
    # A pyramid replaces three wheels that have a torque limit each: say which key.
    (["--envelope", "--wheel-beta", "60", "--set", "wheels.axes=[[1,0,0],[0,1,0],[0,0,1]]",
      "--set", "wheels.max_torque_n_m=[0.1,0.2,0.3]"], "wheels.max_torque_n_m"),
])
def test_bad_options_exit_2_with_one_line(argv, says, capsys):
    assert main(["analyze", *argv]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("allsky: error:") and says in lines[0]


def test_the_flown_dither_torque_is_checked_against_both_envelopes():
    """One axis dithered: the torque is J[:, z] A w^2 sin(w t); margins along that direction."""
    import math

    import numpy as np

    from allsky.config import load_scenario
    from allsky.hardware.jets import make_params
    from allsky.studies.envelope_check import flown_dither_check, wheel_array
    from allsky.vehicle.envelopes import make_envelope

    # 51.2 s period sampled every 0.1 s: a sample falls on each peak of the sine.
    cfg = load_scenario(overrides=["dither.amplitude_urad=[0,0,2000]",
                                   "dither.period_s=[51.2,51.2,51.2]"])
    column = np.asarray(cfg.vehicle.inertia_kg_m2, dtype=float)[:, 2] \
        * cfg.dither.inertia_estimate_scale
    peak = np.abs(column) * 2000e-6 * (2.0 * math.pi / 51.2) ** 2
    out = flown_dither_check(cfg)
    assert out["torque_peak_n_m"] == pytest.approx(peak, rel=1e-12)
    size = float(np.linalg.norm(peak))
    direction = column / np.linalg.norm(column)
    # The jets' couples make a box: the largest multiple of the direction inside it.
    couple = make_params(cfg.jets.thrust_n, cfg.jets.moment_arm_m, cfg.jets.isp_s).torque_n_m
    box_reach = min(c / abs(u) for c, u in zip(couple, direction) if u != 0.0)
    assert out["jets"]["margin"] == pytest.approx(box_reach / size, rel=1e-9)
    array = wheel_array(cfg.wheels)
    reach = make_envelope(array["axes"], array["torque_max_n_m"]).max_along(direction)
    assert out["wheels"]["margin"] == pytest.approx(float(np.ravel(reach)[0]) / size, rel=1e-9)
    assert out["wheels"]["inside"] == (out["wheels"]["margin"] >= 1.0)
