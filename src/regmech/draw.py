"""The dynamic scheme of a model (``Model.draw``): masses as blocks, the devices between them by kind.

The scheme is the drawing of a regular mechanical system that the method of
seed paper 003 starts from: every mass a block, every massless device a
symbol joined by lines to the masses it acts between, the ground drawn
where a device or a mass is fixed to it.

* **Masses** (``Inertia``, ``Mass``; masses joined at one point share one
  block): blue blocks with the name and the inertia or mass.
* **Devices**, a symbol per kind: spring (zigzag), damper (dashpot),
  spring-damper and elastic shaft (both), gear, differential and planetary
  set (a wheel with the ratio), rigid link (a bar), source (a circle with an
  arrow: Torque, Force, Engine; a double circle for prescribed motion:
  Speed, Position), any other device a box with its class name.
* **Friction devices** (clutches, brakes, one-way clutches, friction
  contacts, bearing friction, lossy gears): red, so the places where the
  structure changes (stick/slip) stand out.
* **Ground**: a hatched bar under the device or mass fixed to it
  (a source's free ``support``, which is grounded, too).
* **A massless point** where devices meet without a mass (which the
  regularity rules forbid; ``m.check()`` says why): a red dot.

Layout: the scheme is a graph of masses and devices (from the model's
connection sets, as ``Model.graph`` holds them). It reads as a drivetrain,
left to right along the power path: columns are the distance (in
mass-device steps) from the sources (the first mass when there is none),
the order within a column keeps lines short (barycentre sweeps); a long
scheme wraps into rows of at most ``max_columns`` columns, the lines between
rows dotted. Parts not connected to each other are drawn one below the
other.
"""

from __future__ import annotations

import numpy as np

from .errors import RegmechError
from .io import save_figure

MASS_COLOUR = "#dbe7f5"
FRICTION_COLOUR = "#c44e52"
LINE_COLOUR = "0.25"


# ------------------------------------------------------------------------------------ classification
def _class_names(comp) -> set[str]:
    return {k.__name__ for k in type(comp).__mro__}


def device_symbol(dev) -> str:
    """The symbol a device is drawn with: ``spring``, ``damper``, ``spring_damper``, ``gear``,
    ``rigid``, ``source``, ``motion`` (prescribed position or speed), ``friction``, ``box``."""
    names = _class_names(dev)
    kind = dev.device_kind()
    if kind in ("position", "speed"):
        return "motion"
    if getattr(dev, "is_source", False):
        return "source"
    if names & {"IdealGear", "LossyGear", "Differential", "Planetary", "LossyPlanetary"}:
        return "gear"
    if kind == "friction":
        return "friction"
    if names & {"SpringDamper", "ElastoBacklash"} or ("Shaft" in names and kind != "rigid"
                                                     and getattr(dev, "damping", 0)):
        return "spring_damper"
    if names & {"Spring", "Backlash", "Shaft"} and kind != "rigid":
        return "spring"
    if "Damper" in names:
        return "damper"
    if kind == "rigid":
        return "rigid"
    return "box"


def is_friction(dev) -> bool:
    """A device with stick/slip or loss modes (one that exports a ``mode`` signal)."""
    return dev.device_kind() == "friction" or "FrictionDevice" in _class_names(dev)


def _fmt(v) -> str:
    return f"{v:.3g}"


def device_label(dev) -> str:
    """The name and, for the common kinds, the parameter that sizes it (``c=1e+04``, ``i=3.5``)."""
    p = dev.params()
    names = _class_names(dev)
    extra = ""
    try:
        if "ratio" in p and isinstance(p["ratio"], (int, float)):
            extra = f"i={_fmt(p['ratio'])}"
        elif "c" in p and isinstance(p["c"], (int, float)):
            extra = f"c={_fmt(p['c'])}" + (f", d={_fmt(p['d'])}" if isinstance(p.get("d"), (int, float)) else "")
        elif "Shaft" in names and isinstance(p.get("stiffness"), (int, float)):
            extra = f"c={_fmt(p['stiffness'])}"
        elif "d" in p and isinstance(p["d"], (int, float)):
            extra = f"d={_fmt(p['d'])}"
    except (TypeError, ValueError):          # a parameter given as a signal or table: no value to print
        extra = ""
    return dev.name + (f"\n{extra}" if extra else "")


# ------------------------------------------------------------------------------------ the scheme graph
class Scheme:
    """Masses and devices as a graph (``nodes``: key -> dict(kind, label, ...); ``edges``: (a, b, style)),
    with ground marks (``grounded``: keys fixed to the ground) and the layout (``pos``: key -> (x, y))."""

    def __init__(self, model):
        from .structure.topology import build_nodes
        self.model = model
        self.nodes: dict = {}
        self.edges: list = []
        self.grounded: dict = {}
        nodes, node_of = build_nodes(model)
        key_of = {}
        for nd in nodes:
            if nd.bodies:
                key = f"mass:{nd.index}"
                names = [b.name for b in nd.bodies]
                text = "\n".join(names[:3]) + (f"\n+{len(names) - 3}" if len(names) > 3 else "")
                if len(nd.bodies) == 1:
                    b = nd.bodies[0]
                    unit = "kg m²" if b.mass_param == "J" else "kg"
                    text += f"\n{b.mass_param}={_fmt(b.mass)} {unit}"
                self.nodes[key] = {"kind": "mass", "label": text, "order": min(self._order(b) for b in nd.bodies)}
                if nd.grounded:
                    self.grounded[key] = True
                key_of[nd.index] = key
            elif not nd.grounded and (nd.device_flanges or nd.driven_by):
                key = f"point:{nd.index}"
                devs = {id(f.component) for f in nd.device_flanges + nd.driven_by}
                # a massless point between devices (a regularity error), or a driven point
                self.nodes[key] = {"kind": "point" if len(devs) > 1 and not nd.driven_by else "end",
                                   "label": "", "order": 10 ** 9}
                key_of[nd.index] = key
        for comp in model.components.values():
            if comp.role != "device":
                continue
            key = f"dev:{comp.name}"
            self.nodes[key] = {"kind": device_symbol(comp), "friction": is_friction(comp), "label":
                               device_label(comp), "order": self._order(comp), "component": comp}
            for fl in comp.flange_list:
                nd = node_of.get(fl)
                if nd is None:
                    continue
                target = key_of.get(nd.index)
                if target is None:
                    if nd.grounded:
                        self.grounded[key] = True
                    continue
                if (key, target) not in [(a, b) for a, b, _ in self.edges]:
                    self.edges.append((key, target, "line"))
        self.pos: dict = {}

    def _order(self, comp) -> int:
        if not hasattr(self, "_orders"):
            self._orders = {name: i for i, name in enumerate(self.model.components)}
        return self._orders.get(comp.name, 10 ** 9)

    # ---------------------------------------------------------------------------------------- layout
    def layout(self, max_columns: int = 18):
        """Columns by distance from the sources, rows by barycentre; wrapped after ``max_columns``."""
        import networkx as nx
        g = nx.Graph()
        g.add_nodes_from(self.nodes)
        g.add_edges_from((a, b) for a, b, _ in self.edges)
        parts = sorted(nx.connected_components(g), key=lambda c: min(self.nodes[k]["order"] for k in c))
        y0 = 0.0
        self.bands = []
        for part in parts:
            sub = g.subgraph(part)
            roots = [k for k in part if self.nodes[k]["kind"] in ("source", "motion")]
            if not roots:
                masses = [k for k in part if self.nodes[k]["kind"] == "mass"]
                roots = [min(masses or part, key=lambda k: self.nodes[k]["order"])]
            depth = nx.multi_source_dijkstra_path_length(sub, roots)
            layers: dict = {}
            for k, d in depth.items():
                layers.setdefault(int(d), []).append(k)
            for d in layers:
                layers[d].sort(key=lambda k: self.nodes[k]["order"])
            n_layers = max(layers) + 1
            # barycentre sweeps: a node's row follows the mean row of its neighbours in the column before
            # (then after); a few sweeps settle the crossings of a drivetrain
            rank = {k: i for d in layers for i, k in enumerate(layers[d])}
            for sweep in range(6):
                cols = range(1, n_layers) if sweep % 2 == 0 else range(n_layers - 2, -1, -1)
                for d in cols:
                    ref = d - 1 if sweep % 2 == 0 else d + 1
                    def bary(k):
                        nb = [rank[n] for n in sub.neighbors(k) if depth[n] == ref]
                        return (np.mean(nb) if nb else rank[k], self.nodes[k]["order"])
                    layers[d].sort(key=bary)
                    for i, k in enumerate(layers[d]):
                        rank[k] = i
            width = max(len(v) for v in layers.values())
            n_bands = (n_layers + max_columns - 1) // max_columns
            per_band = (n_layers + n_bands - 1) // n_bands        # bands of equal length
            band_h = width + 1.4
            for d, keys in layers.items():
                band, col = divmod(d, per_band)
                for i, k in enumerate(keys):
                    self.pos[k] = (float(col), y0 - band * band_h - (i - (len(keys) - 1) / 2.0))
            self.bands.append((y0, n_bands, band_h, per_band))
            y0 -= n_bands * band_h + 0.6
        return self.pos


# ------------------------------------------------------------------------------------ drawing
def draw_model(model, path=None, ax=None, max_columns: int = 18, figsize=None, title=None):
    """Draw the dynamic scheme of ``model`` (see the module docstring). Returns the matplotlib figure;
    ``path`` writes it (PNG, SVG, PDF by the suffix)."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise RegmechError("Model.draw() needs matplotlib: pip install 'regmech[plot]'") from None
    if not model.components:
        raise RegmechError(f"model '{model.name}' has no components to draw; add some with m.add(...)")
    sch = Scheme(model)
    pos = sch.layout(max_columns=max_columns)
    xs = [p[0] for p in pos.values()] or [0.0]
    ys = [p[1] for p in pos.values()] or [0.0]
    n_key = len(_key(sch))
    rows = _key_rows(sch, max(ys) - min(ys) + 0.6)
    key_cols = (n_key + rows - 1) // rows
    key_h = KEY_STEP * (min(rows, n_key) - 1)
    span_x = max(xs) - min(xs) + 1.6 + 1.1 + KEY_WIDTH * key_cols   # the scheme and the key beside it
    span_y = max(max(ys) - min(ys), key_h) + 1.6
    scale = 1.15
    size = figsize or (max(6.0, span_x * scale + 0.6), max(3.0, span_y * scale + 1.0))
    if ax is None:
        if path is not None:
            from .plotting import _pyplot_free_figure
            fig = _pyplot_free_figure(size)
        else:
            import matplotlib.pyplot as plt
            fig = plt.figure(figsize=size)
        ax = fig.add_axes([0.01, 0.01, 0.98, 0.9])
    else:
        fig = ax.figure
    right = max(xs) + 0.55
    for a, b, _ in sch.edges:
        (xa, ya), (xb, yb) = pos[a], pos[b]
        if xb < xa:
            (xa, ya), (xb, yb) = (xb, yb), (xa, ya)
        if xb - xa > 1.5:           # wrapped into the next row: round the right end, back along the gap
            if ya < yb:
                (xa, ya), (xb, yb) = (xb, yb), (xa, ya)
            mid = _gap_below(sch, ya)
            ax.plot([xa, right, right, -0.55, -0.55, xb], [ya, ya, mid, mid, yb, yb], color=LINE_COLOUR, lw=0.9,
                    ls=":", zorder=1)
        else:
            ax.plot([xa, xb], [ya, yb], color=LINE_COLOUR, lw=1.4, zorder=1)
    font = 7.5 if len(sch.nodes) <= 60 else 6
    for key, nd in sch.nodes.items():
        x, y = pos[key]
        kind = nd["kind"]
        if kind == "mass":
            _block(ax, x, y, nd["label"], font)
        elif kind in ("point", "end"):
            ax.plot([x], [y], "o", color=FRICTION_COLOUR if kind == "point" else LINE_COLOUR, ms=5, zorder=3)
            if kind == "point":
                ax.text(x, y - 0.18, "massless\npoint", ha="center", va="top", fontsize=font - 1,
                        color=FRICTION_COLOUR)
        else:
            _device(ax, x, y, nd, font, label_above=key in sch.grounded)
        if key in sch.grounded:          # a device's name then sits above it, out of the hatching's way
            _ground(ax, x, y - (0.36 if kind == "mass" else 0.3))
    key_x = max(xs) + 1.3
    _draw_key(ax, sch, key_x, max(ys), font, rows)
    ax.set_xlim(min(xs) - 0.8, key_x + KEY_WIDTH * key_cols - 0.2)
    ax.set_ylim(min(min(ys), max(ys) - key_h) - 0.8, max(ys) + 0.75)
    ax.set_aspect("equal")
    ax.axis("off")
    n_mass = sum(1 for n in sch.nodes.values() if n["kind"] == "mass")
    n_dev = sum(1 for n in sch.nodes.values() if n["kind"] not in ("mass", "point", "end"))
    n_fr = sum(1 for n in sch.nodes.values() if n.get("friction"))
    ax.set_title(title or f"{model.name}: dynamic scheme ({n_mass} masses, {n_dev} devices, {n_fr} with "
                 f"friction)", loc="left", fontsize=10)
    if path is not None:
        save_figure(fig, path, "draw")
    return fig


def _gap_below(sch, y) -> float:
    """The y of the gap under the row of the scheme that holds ``y`` (for lines to the next row)."""
    for y0, n_bands, band_h, _ in sch.bands:
        for band in range(n_bands):
            top = y0 - band * band_h + band_h / 2
            if top - band_h <= y <= top + 0.5:
                return top - band_h + 0.45
    return y - 0.7


def _wrap_name(text: str, width: int = 14) -> str:
    """Long dotted names over two lines (``wheel_left.`` / ``tread``) so that they fit a block."""
    out = []
    for line in text.split("\n"):
        if len(line) > width and "." in line:
            head, _, tail = line.rpartition(".")
            out += [head + ".", tail]
        else:
            out.append(line)
    return "\n".join(out)


def _block(ax, x, y, label, font):
    from matplotlib.patches import FancyBboxPatch
    label = _wrap_name(label)
    lines = label.split("\n")
    w, h = 0.84, max(0.62, 0.14 * len(lines) + 0.14)
    ax.add_patch(FancyBboxPatch((x - w / 2, y - h / 2), w, h, boxstyle="round,pad=0.0,rounding_size=0.05",
                                fc=MASS_COLOUR, ec="#2f4b7c", lw=1.3, zorder=4))
    longest = max(len(s) for s in lines)
    ax.text(x, y, label, ha="center", va="center", fontsize=font * min(1.0, 13.0 / max(longest, 1)), zorder=5,
            linespacing=1.05)


def _ground(ax, x, y):
    ax.plot([x - 0.2, x + 0.2], [y, y], color="k", lw=1.4, zorder=3)
    for i in range(5):
        xi = x - 0.2 + 0.1 * i
        ax.plot([xi, xi - 0.07], [y, y - 0.08], color="k", lw=0.8, zorder=3)


def _device(ax, x, y, nd, font, label_above=False):
    from matplotlib.patches import Circle, Rectangle
    kind = nd["kind"]
    col = FRICTION_COLOUR if nd.get("friction") else "k"
    bg = dict(fc="white", ec=col, lw=1.3, zorder=4)
    s = 0.2
    if kind in ("spring", "spring_damper"):
        ax.add_patch(Rectangle((x - s, y - s), 2 * s, 2 * s, fc="white", ec="none", zorder=3))
        zx = np.linspace(x - s, x + s, 9)
        zy = y + (0.07 if kind == "spring_damper" else 0.0) + np.r_[0, [0.06, -0.06] * 3, 0.06, 0]
        ax.plot(zx, zy, color=col, lw=1.2, zorder=4)
        if kind == "spring_damper":
            _dashpot(ax, x, y - 0.08, col, small=True)
    elif kind == "damper":
        ax.add_patch(Rectangle((x - s, y - s), 2 * s, 2 * s, fc="white", ec="none", zorder=3))
        _dashpot(ax, x, y, col)
    elif kind == "gear":
        ax.add_patch(Circle((x, y), s, **bg))
        ax.add_patch(Circle((x, y), s * 0.55, fc="none", ec=col, lw=0.9, ls="--", zorder=5))
    elif kind == "source":
        ax.add_patch(Circle((x, y), s, **bg))
        ax.annotate("", xy=(x + 0.1, y + 0.06), xytext=(x - 0.1, y - 0.06),
                    arrowprops=dict(arrowstyle="->", color=col, lw=1.2, connectionstyle="arc3,rad=0.5"), zorder=6)
    elif kind == "motion":
        ax.add_patch(Circle((x, y), s, **bg))
        ax.add_patch(Circle((x, y), s * 0.6, fc="none", ec=col, lw=1.0, zorder=5))
    elif kind == "friction":
        ax.add_patch(Rectangle((x - s, y - s), 2 * s, 2 * s, fc="white", ec="none", zorder=3))
        for dx in (-0.05, 0.05):
            ax.plot([x + dx, x + dx], [y - 0.17, y + 0.17], color=col, lw=3.0, zorder=4)
    elif kind == "rigid":
        ax.add_patch(Rectangle((x - s, y - 0.05), 2 * s, 0.1, fc=col, ec=col, zorder=4))
    else:
        ax.add_patch(Rectangle((x - 0.28, y - 0.13), 0.56, 0.26, **bg))
        ax.text(x, y, type(nd["component"]).__name__[:12] if nd["component"] is not None else "", ha="center",
                va="center", fontsize=font - 2.0,
                color=col, zorder=5)
    if label_above:
        ax.text(x, y + s + 0.04, nd["label"], ha="center", va="bottom", fontsize=font - 0.5, color=col, zorder=6,
                linespacing=1.0)
    else:
        ax.text(x, y - s - 0.04, nd["label"], ha="center", va="top", fontsize=font - 0.5, color=col, zorder=6,
                linespacing=1.0)


def _dashpot(ax, x, y, col, small=False):
    h = 0.06 if small else 0.1
    ax.plot([x - 0.2, x - 0.02], [y, y], color=col, lw=1.1, zorder=4)
    ax.plot([x - 0.02, x - 0.02], [y - h * 0.7, y + h * 0.7], color=col, lw=1.6, zorder=4)
    ax.plot([x - 0.08, x + 0.1, x + 0.1, x - 0.08], [y + h, y + h, y - h, y - h], color=col, lw=1.1, zorder=4)
    ax.plot([x + 0.1, x + 0.2], [y, y], color=col, lw=1.1, zorder=4)


def _key(sch):
    """The kinds present, in a fixed order, with their explanation: (kind, friction, text)."""
    present = {n["kind"] for n in sch.nodes.values()}
    rows = [("mass", False, "mass (J or m)"), ("spring", False, "spring (c)"), ("damper", False, "damper (d)"),
            ("spring_damper", False, "spring-damper, shaft"), ("gear", False, "gear set (ratio i)"),
            ("rigid", False, "rigid link"), ("source", False, "source: torque, force"),
            ("motion", False, "prescribed speed, position"), ("box", False, "other device (class)"),
            ("point", False, "massless point (not regular)")]
    # red symbols: devices that stick and slip (a lossy gear is a red gear)
    out = [r for r in rows if r[0] in present]
    if any(n.get("friction") for n in sch.nodes.values()):
        out.append(("friction", True, "friction device (red)"))
    if sch.grounded:
        out.append(("ground", False, "ground"))
    return out


KEY_STEP = 0.45         # vertical step of the key's rows
KEY_WIDTH = 2.6         # width of one column of the key


def _key_rows(sch, height) -> int:
    """Rows per column of the key: as many as fit the scheme's height (at least 3)."""
    return max(3, int(height / KEY_STEP) + 1)


def _draw_key(ax, sch, x_left, y_top, font, rows):
    """The key to the symbols, drawn with the symbols themselves, in columns of ``rows`` from ``x_left``."""
    ax.text(x_left - 0.25, y_top + 0.2, "key", fontsize=font + 0.5, fontweight="bold", va="bottom")
    for i, (kind, fr, text) in enumerate(_key(sch)):
        col, row = divmod(i, rows)
        x0, y = x_left + col * KEY_WIDTH, y_top - KEY_STEP * row
        if kind == "mass":
            from matplotlib.patches import FancyBboxPatch
            ax.add_patch(FancyBboxPatch((x0 - 0.2, y - 0.14), 0.4, 0.28, boxstyle="round,pad=0,rounding_size=0.04",
                                        fc=MASS_COLOUR, ec="#2f4b7c", lw=1.2, zorder=4))
        elif kind == "ground":
            _ground(ax, x0, y)
        elif kind == "point":
            ax.plot([x0], [y], "o", color=FRICTION_COLOUR, ms=5)
        else:
            _device(ax, x0, y, {"kind": kind, "friction": fr, "label": "", "component": None}, font)
        ax.text(x0 + 0.32, y, text, fontsize=font, va="center", ha="left")
