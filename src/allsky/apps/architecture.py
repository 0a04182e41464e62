"""The layers picture of ``docs/architecture.md``, drawn from the code's imports.

Each package of :data:`allsky.layers.LAYERS` is a band, top to bottom, with
its modules listed inside; each arrow is the imports between two packages,
counted from the source (:func:`allsky.layers.import_graph`), so the picture
shows the code as it is, not as it was meant to be.
"""

from pathlib import Path

from allsky import layers


def package_modules(graph: dict) -> dict:
    """Package -> sorted short module names (package faces left out).

    ``graph`` is the import graph (:func:`allsky.layers.import_graph`); only
    its modules are read.
    """
    out = {layer.package: [] for layer in layers.LAYERS}
    for module in graph:
        pkg = layers.package_of(module)
        short = module.split(".")[-1]
        if module in ("allsky", f"allsky.{pkg}") or short.startswith("__"):
            continue
        out[pkg].append(short)
    return {k: sorted(v) for k, v in out.items()}


def layers_figure(path=None):
    """Draw the layers and the counted imports between them; save to ``path`` if given."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

    graph = layers.import_graph()
    modules = package_modules(graph)
    edges = layers.package_edges(graph)
    n = len(layers.LAYERS)
    band_h, gap, width = 1.0, 0.45, 14.0
    fig, ax = plt.subplots(figsize=(12, 0.95 * n + 0.8))
    ax.set_xlim(-0.2, width + 3.2)
    ax.set_ylim(-0.3, n * (band_h + gap))
    ax.axis("off")
    centre_y = {}
    for i, layer in enumerate(layers.LAYERS):
        y = (n - 1 - i) * (band_h + gap)
        centre_y[layer.package] = y + band_h / 2
        ax.add_patch(FancyBboxPatch((0, y), width, band_h, boxstyle="round,pad=0.02",
                                    facecolor="#e8eef6", edgecolor="#4e79a7", linewidth=1.2))
        name = f"{layer.package}/" if layer.package else "allsky/*.py"
        ax.text(0.15, y + band_h - 0.2, f"{name}  —  {layer.title}", fontsize=10,
                fontweight="bold", va="top")
        ax.text(0.15, y + band_h - 0.5, layer.holds, fontsize=8, va="top", color="#333333")
        ax.text(0.15, y + 0.08, ", ".join(modules[layer.package]), fontsize=6.5, va="bottom",
                color="#555555", wrap=True)
    # Arrows on the right-hand side: importing band -> imported band, offset by distance.
    for k, ((a, b), count) in enumerate(sorted(edges.items(),
                                               key=lambda e: layers.RANK[e[0][0]]
                                               - layers.RANK[e[0][1]])):
        x = width + 0.25 + 0.12 * (k % 24)
        up = layers.RANK[b] > layers.RANK[a]
        ax.add_patch(FancyArrowPatch((x, centre_y[a]), (x, centre_y[b]), arrowstyle="-|>",
                                     mutation_scale=7, linewidth=0.6 + 0.08 * min(count, 20),
                                     color="#e15759" if up else "#59a14f", alpha=0.8))
    ax.set_title("allsky: packages as layers (imports go down only; "
                 "arrows = imports counted from the source)", fontsize=10)
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
    return fig


def layers_table() -> str:
    """Markdown table of the layers, top to bottom, with their modules."""
    modules = package_modules(layers.import_graph())
    lines = ["| layer | folder | holds | modules |", "|---|---|---|---|"]
    for layer in layers.LAYERS:
        folder = f"`src/allsky/{layer.package}/`" if layer.package else "`src/allsky/*.py`"
        mods = ", ".join(f"`{m}`" for m in modules[layer.package])
        lines.append(f"| {layer.title} | {folder} | {layer.holds} | {mods} |")
    return "\n".join(lines) + "\n"
