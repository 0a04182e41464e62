"""Figures of the three-axis Kalman filter: what each manoeuvre makes observable.

``python -m allsky.apps.kalman_plots DIR`` flies the default scenario twice,
the legacy plan and the dither plan, runs the filter of
:mod:`allsky.studies.kalman_mekf` on each, and writes
``DIR/kalman_observability.png``: the filter's 1-sigma of the scale factors
and the misalignments against mission time through the Sun-and-star hold
(Mode 3), the 360 deg roll (Mode 4), the pitch, 360 deg yaw and pitch back
(Mode 5), and, on the other plan, through the dither hold.
"""

import sys
from pathlib import Path

import numpy as np

from allsky.sequencer.modes import MODE_CODE
from allsky.studies import kalman_mekf

#: Shading and label of the modes the filter runs through.
_SHADE = {"3": ("0.92", "Mode 3: hold"), "4": ("#dbe9f6", "Mode 4: 360° roll"),
          "5": ("#f6e3d0", "Mode 5: pitch, 360° yaw, pitch back"),
          "dither": ("#e2f0d9", "dither hold")}
_SF_LABELS = ("roll (gyro 1)", "pitch (gyro 2)", "yaw (gyro 3)")


def _mis_label(i, j):
    axes = "xyz"
    return f"M{i + 1}{axes[j]}: gyro {i + 1} to body {axes[j]}"


def observability_figure(legacy: kalman_mekf.Observability,
                         dither: kalman_mekf.Observability):
    """Sigmas of scale factors and misalignments against time, legacy beside dither.

    Parameters
    ----------
    legacy, dither : allsky.studies.kalman_mekf.Observability
        The filter through Modes 3-5 and through Mode 3 and the dither hold.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 7.2), layout="constrained")
    axs = fig.subplots(2, 2, sharey="row", sharex="col")
    for col, (obs, title) in enumerate(((legacy, "the patent's manoeuvres (Modes 3-5)"),
                                        (dither, "the dither hold"))):
        t = obs.time_s
        for row, (data, labels, unit) in enumerate((
                (obs.scale_factor_ppm, _SF_LABELS, "ppm"),
                (obs.misalignment_arcsec,
                 [_mis_label(i, j) for i, j in kalman_mekf.MISALIGNMENT_PAIRS], "arcsec"))):
            ax = axs[row, col]
            for name, (shade, text) in _SHADE.items():
                inside = obs.mode == MODE_CODE[name]
                if np.any(inside):
                    ax.axvspan(t[inside][0], t[inside][-1], color=shade, lw=0,
                               label=text if row == 0 else None)
            for k in range(data.shape[1]):
                ax.plot(t, data[:, k], lw=1.2, label=labels[k], color=f"C{k}",
                        ls="-" if k < 3 else "--")
            ax.set_yscale("log")
            ax.grid(True, which="both", alpha=0.3)
            if col == 0:
                ax.set_ylabel(f"1-sigma [{unit}]")
            if row == 0:
                ax.set_title(f"Scale factors through {title}")
            else:
                ax.set_title(f"Misalignments through {title}")
                ax.set_xlabel("mission time [s]")
            ax.legend(fontsize=7, loc="center right", ncol=2)
    fig.suptitle("What the three-axis Kalman filter can learn: sigmas against time "
                 "(default scenario, seed 1)")
    return fig


def mismatch_figure(study: dict):
    """The filter under a wrong model (:func:`allsky.studies.mismatch.study_dict`).

    ``study`` is that function's result.

    Left: the noise data sheet scaled by k (all noises, the gyro's, the
    optics'): the mean NEES at the end of Mode 5 (15 expected) and the RMS
    roll and yaw scale-factor errors over the filter's own sigma (1 for an
    honest filter), against k. Right: a misaligned tracker, a biased sun
    sensor, a catalog error, against the angle: the final pointing's RMS,
    beside the filter with the right model and the legacy turns' own.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.4), layout="constrained")
    ax_n, ax_r, ax_p = fig.subplots(1, 3, width_ratios=(1, 1, 1.3))
    cases = study["cases"]
    for group, colour in (("noise", "C0"), ("gyro noise", "C1"), ("optics noise", "C2")):
        mine = sorted((c for c in cases if c["group"] == group or (
            group != "noise" and c["group"] == "noise" and c["value"] == 1.0)),
            key=lambda c: c["value"])
        k = [c["value"] for c in mine]
        ax_n.plot(k, [study["nees"][c["name"]] for c in mine], "o-", color=colour,
                  label=f"{group} x k")
        ratio = [np.mean([study["rms"][c["name"]]["scale_factor_ppm"][a]
                          / study["sigma"][c["name"]]["scale_factor_ppm"][a]
                          for a in ("roll", "yaw")]) for c in mine]
        ax_r.plot(k, ratio, "o-", color=colour, label=f"{group} x k")
    ax_n.axhline(15.0, color="k", lw=0.8, ls="--", label="15 states: consistent")
    ax_r.axhline(1.0, color="k", lw=0.8, ls="--", label="honest")
    for ax in (ax_n, ax_r):
        ax.set_xscale("log")
        ax.minorticks_off()
        ax.set_xticks([0.5, 0.71, 1, 1.41, 2], ["0.5", "0.71", "1", "1.41", "2"])
        ax.set_xlabel("noise the filter assumes / true noise, k")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    ax_n.set_yscale("log")
    ax_n.set_ylabel("mean NEES at the end of Mode 5")
    ax_n.set_title("What the filter claims")
    ax_r.set_ylabel("RMS scale-factor error / filter sigma")
    ax_r.set_title("Its honesty")
    right = next(c for c in cases if c["group"] == "noise" and c["value"] == 1.0)["name"]
    for group, marker in (("tracker about x", "o"), ("tracker about z", "s"),
                          ("sun bias", "^"), ("catalog", "D")):
        mine = sorted((c for c in cases if c["group"] == group), key=lambda c: c["value"])
        ax_p.plot([c["value"] for c in mine],
                  [study["pointing_arcsec"][c["name"]]["rms"] for c in mine],
                  marker + "-", label=group)
    ax_p.axhline(study["pointing_arcsec"][right]["rms"], color="C0", lw=0.8, ls="--",
                 label="filter, right model")
    ax_p.axhline(study["legacy_pointing_arcsec"]["rms"], color="k", lw=0.8, ls=":",
                 label="legacy turns (use no model)")
    ax_p.set_xscale("log")
    ax_p.set_yscale("log")
    ax_p.set_xlabel("misalignment, bias or catalog error [arcsec]")
    ax_p.set_ylabel("final pointing, RMS over the seeds [arcsec]")
    ax_p.set_title("What it costs the pointing")
    ax_p.grid(True, which="both", alpha=0.3)
    ax_p.legend(fontsize=7)
    fig.suptitle(f"The three-axis filter through Modes 3-5 with a wrong model "
                 f"({study['runs']} seeds of the default scenario)")
    return fig


def write_figures(out_dir, cfg=None) -> list:
    """Fly both plans, filter them, write ``kalman_observability.png`` in ``out_dir``.

    ``cfg`` is the scenario flown (None: the packaged default). Returns the
    paths written.
    """
    from allsky.apps.output import write_atomic
    from allsky.config import load_scenario

    cfg = cfg or load_scenario()
    obs = [kalman_mekf.observability(kalman_mekf.fly(cfg, plan, through_mode6=False).estimate)
           for plan in ("legacy", "dither")]
    path = Path(out_dir) / "kalman_observability.png"
    write_atomic(path, writer=lambda tmp: observability_figure(*obs).savefig(tmp, dpi=110),
                 option="DIR")
    return [path]


if __name__ == "__main__":
    for p in write_figures(sys.argv[1] if len(sys.argv) > 1 else "."):
        print(f"wrote {p}")
