"""Interactive figures of a run report: plotly figure specs built as plain data, drawn by plotly.js.

A figure is a plotly ``{"data": [...], "layout": {...}}`` document whose large
arrays live once per page in an :class:`Arrays` store (float32, base64) and are
referenced from the traces as ``"@<key>"`` strings; ``assets/legbench.js``
(:data:`LEGBENCH_JS`) decodes them and calls plotly.js, which is written once
per results tree (:func:`write_assets`) and read from there by every page, so a
page works from ``file://`` with no network.

Figures (every time axis in seconds, every value in its signal's unit):

* overlays: each signal's three components in three rows with one shared time
  axis, every backend;
* deviations from the reference backend, the same way;
* focus on the transients: the largest deviation of each signal at full
  resolution in a window around it;
* focus on the steady state: the joint-angle deviation over the steady window
  at full resolution (differences of 1e-5 rad are visible there);
* the leg of every backend in 3D with a time slider, drawn through
  :func:`legbench.kinematics.chain` from the logged joint angles, with the
  ground plane and the foot. The kinematics are the *active* model's (the
  parameter file of the process writing the report), so the view is drawn
  only when the run used that model (:func:`model_match`: run.json's ``urdf``
  against the name :func:`legbench.resources.urdf_target` gives the active
  model's URDF); otherwise it is left out and :func:`model_advice` says how
  to get it.

Long series are decimated for display with a min/max envelope
(:func:`envelope`): each bin keeps its smallest and largest sample, so a
millisecond contact transient keeps its height however long the run.
"""

from __future__ import annotations

import base64
import hashlib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from legbench import kinematics
from legbench.compare import ComparisonResult
from legbench.resources import bundled_urdf, urdf_name
from legbench.resources import shown as shown_file
from legbench.results import Run, RunResult, atomic_write_bytes, atomic_write_text
from legbench.signals import JOINTS, SIGNALS, SLICE, UNITS
from legbench.signals import label as column_label

__all__ = [
    "BINS",
    "LEGBENCH_JS",
    "Arrays",
    "Figure",
    "ModelMatch",
    "envelope",
    "model_advice",
    "model_match",
    "no_ground_force",
    "run_figures",
    "run_title",
    "write_assets",
]

#: Bins of the display envelope: at most 2 * BINS points per trace.
BINS = 500
#: Half-width of the focused window around a largest deviation [s].
FOCUS_HALF_WIDTH = 0.05
#: Frames of the 3D leg view (its time slider's steps).
LEG_FRAMES = 200
#: The directory of shared assets in a results tree, and the files in it.
ASSETS = "assets"
PLOTLY_JS = "plotly.min.js"
LEGBENCH_FILE = "legbench.js"

NAMES = {
    "q": "joint angle",
    "qd": "joint velocity",
    "tau": "joint torque",
    "force": "ground force on the foot (W)",
    "ee": "foot centre position (W)",
}
_PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf")
_DASHES = ("solid", "dash", "dot", "dashdot", "longdash", "longdashdot")  # one per non-reference backend of the seven

#: The page-side loader: decodes the float32 arrays and draws the figures and the leg view.
LEGBENCH_JS = r"""/* legbench report figures: decode float32 arrays, draw with plotly.js (loaded before). */
(function () {
  "use strict";
  var store = {};
  function decode(b64) {
    var s = atob(b64), n = s.length, u = new Uint8Array(n);
    for (var i = 0; i < n; i++) u[i] = s.charCodeAt(i);
    return new Float32Array(u.buffer);
  }
  function get(v) {
    if (typeof v === "string" && v.charAt(0) === "@") {
      var a = store[v.slice(1)];
      if (!a) throw new Error("legbench: no array " + v);
      return a;
    }
    return v;
  }
  function resolve(tr) {
    ["x", "y", "z"].forEach(function (k) { if (k in tr) tr[k] = get(tr[k]); });
    return tr;
  }
  var config = {responsive: true, displaylogo: false, scrollZoom: false};
  function leg(id, spec) {
    var el = document.getElementById(id), n = spec.times.length, nb = spec.backends.length;
    var data = spec.static.map(resolve), idx = [];
    function pose(b, k) {
      var p = get(spec.backends[b].points), o = k * 15, x = [], y = [], z = [];
      for (var j = 0; j < 5; j++) { x.push(p[o + 3 * j]); y.push(p[o + 3 * j + 1]); z.push(p[o + 3 * j + 2]); }
      return [x, y, z];
    }
    for (var b = 0; b < nb; b++) {
      var xyz = pose(b, 0), be = spec.backends[b];
      data.push({type: "scatter3d", mode: "lines+markers", name: be.name, legendgroup: be.name,
                 x: xyz[0], y: xyz[1], z: xyz[2], line: {color: be.color, width: be.width},
                 marker: {color: be.color, size: [3, 4, 4, 4, spec.foot_size]}});
      idx.push(data.length - 1);
    }
    Plotly.newPlot(el, data, spec.layout, config);
    var slider = document.getElementById(id + "-slider"), label = document.getElementById(id + "-time");
    var play = document.getElementById(id + "-play"), timer = null;
    function show(k) {
      var xs = [], ys = [], zs = [];
      for (var b = 0; b < nb; b++) { var p = pose(b, k); xs.push(p[0]); ys.push(p[1]); zs.push(p[2]); }
      Plotly.restyle(el, {x: xs, y: ys, z: zs}, idx);
      label.textContent = "t = " + spec.times[k].toFixed(3) + " s";
    }
    slider.max = n - 1;
    slider.addEventListener("input", function () { show(+slider.value); });
    play.addEventListener("click", function () {
      if (timer) { clearInterval(timer); timer = null; play.textContent = "play"; return; }
      play.textContent = "pause";
      timer = setInterval(function () {
        var k = (+slider.value + 1) % n; slider.value = k; show(k);
        if (k === n - 1) { clearInterval(timer); timer = null; play.textContent = "play"; }
      }, 50);
    });
    show(0);
  }
  window.legbench = {
    data: function (arrays) { for (var k in arrays) store[k] = decode(arrays[k]); },
    plot: function (id, spec) { Plotly.newPlot(id, spec.data.map(resolve), spec.layout, config); },
    leg: leg
  };
})();
"""


def write_assets(directory: Path) -> Path:
    """Write plotly.min.js (from the plotly package) and legbench.js into ``directory`` once; returns it.

    plotly.min.js is copied only when absent or of another size (another plotly version).
    """
    directory.mkdir(parents=True, exist_ok=True)
    src = resources.files("plotly") / "package_data" / PLOTLY_JS
    dst = directory / PLOTLY_JS
    with resources.as_file(src) as path:
        if not dst.is_file() or dst.stat().st_size != path.stat().st_size:
            atomic_write_bytes(dst, path.read_bytes())  # 4.8 MB once per tree; a failed copy leaves no temporary
    js = directory / LEGBENCH_FILE
    if not js.is_file() or js.read_text() != LEGBENCH_JS:
        atomic_write_text(js, LEGBENCH_JS)
    return directory


# --------------------------------------------------------------------------- #
# Data


@dataclass
class Arrays:
    """The float32 arrays of one page, stored once each and referenced as ``"@<key>"``."""

    items: dict[str, str] = field(default_factory=dict)
    _by_digest: dict[bytes, str] = field(default_factory=dict)

    def ref(self, a: np.ndarray) -> str:
        """Store ``a`` (any float array, flattened to float32) and return its reference."""
        raw = np.ascontiguousarray(a, dtype="<f4").tobytes()
        digest = hashlib.blake2b(raw, digest_size=16).digest()
        key = self._by_digest.get(digest)
        if key is None:
            key = f"a{len(self.items)}"
            self._by_digest[digest] = key
            self.items[key] = base64.b64encode(raw).decode("ascii")
        return "@" + key

    @property
    def nbytes(self) -> int:
        """Characters of base64 held."""
        return sum(len(v) for v in self.items.values())


@dataclass(frozen=True)
class ModelMatch:
    """The leg model a run used against the active one, by their URDF file names.

    run.json's ``urdf`` is the file name of the URDF the run was made with: ``leg.urdf`` for the bundled model,
    ``<stem>-<hash of the parameter file>.urdf`` for any other (:func:`legbench.resources.urdf_target`), so equal
    names mean the same parameter file's content (for the bundled model: whatever the bundled file held then).

    Attributes:
        run: the run's URDF name (run.json ``urdf``), or None when run.json names none.
        active: the active model's URDF name, as :func:`legbench.resources.urdf_target` names it.
    """

    run: str | None
    active: str

    @property
    def differs(self) -> bool:
        """True when run.json names another model than the active one (False when it names none)."""
        return self.run is not None and self.run != self.active


def model_match(run: Run) -> ModelMatch:
    """The run's leg model (run.json ``urdf``) against the active one (``--model``, ``LEGBENCH_MODEL``, the bundled
    leg): every figure or check drawn through :mod:`legbench.kinematics` uses the active model's geometry."""
    urdf = run.meta.get("urdf")
    name = Path(urdf).name if isinstance(urdf, str) and urdf.strip() else None
    return ModelMatch(name or None, urdf_name())


def model_advice(match: ModelMatch, run: Run) -> str:
    """How to report ``run`` with its own model: the command, and which parameter file FILE is."""
    urdf = match.run or ""
    if urdf == bundled_urdf().name:
        which = "the bundled leg, legbench/data/models/leg.yaml (models/leg.yaml in a source checkout)"
    else:
        stem, _, digest = Path(urdf).stem.rpartition("-")
        which = (
            f"the run's parameter file ({stem}.yaml, with the content it had for the run: {urdf} is named by a "
            "hash of that content)"
            if stem and digest
            else f"the run's parameter file (its URDF was {urdf})"
        )
    return f"`legbench --model FILE compare {shown_file(run.path)}` with FILE {which}"


def envelope(t: np.ndarray, y: np.ndarray, bins: int = BINS) -> tuple[np.ndarray, np.ndarray]:
    """Min/max envelope of ``y`` (shape (n,) or (n, m)) over ``bins`` equal runs of samples.

    Each bin becomes two points, its minimum and its maximum, each at the time of
    its own sample, in the order they occur (so a peak is drawn exactly where it
    is); a series of at most ``2 * bins`` samples is returned as it is. NaN
    samples are ignored (a bin of NaN stays NaN: a gap). The columns of a 2-D
    ``y`` have their extremes at different samples, so each has its own times.

    Returns:
        (times [s], values), of equal shape: (2 bins,) for a 1-D ``y``, (2 bins, m) for a 2-D one
        (column j's times are ``times[:, j]``).
    """
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    n = len(t)
    two_d = y.ndim == 2
    if n <= 2 * bins:
        return (np.broadcast_to(t[:, None], y.shape) if two_d else t), y
    y2 = y if two_d else y[:, None]
    k = math.ceil(n / bins)
    nb = math.ceil(n / k)
    pad = nb * k - n
    yp = np.concatenate([y2, np.repeat(y2[-1:], pad, axis=0)]) if pad else y2
    blocks = yp.reshape(nb, k, y2.shape[1])
    nan = np.isnan(blocks)
    lo_i = np.argmin(np.where(nan, np.inf, blocks), axis=1)
    hi_i = np.argmax(np.where(nan, -np.inf, blocks), axis=1)
    lo = np.take_along_axis(blocks, lo_i[:, None, :], axis=1)[:, 0, :]
    hi = np.take_along_axis(blocks, hi_i[:, None, :], axis=1)[:, 0, :]
    lo_first = lo_i <= hi_i
    out = np.empty((2 * nb, y2.shape[1]))
    out[0::2], out[1::2] = np.where(lo_first, lo, hi), np.where(lo_first, hi, lo)
    starts = (np.arange(nb) * k)[:, None]
    idx = np.empty((2 * nb, y2.shape[1]), dtype=np.intp)  # sample index of each point (never a padding row)
    idx[0::2] = np.minimum(starts + np.minimum(lo_i, hi_i), n - 1)
    idx[1::2] = np.minimum(starts + np.maximum(lo_i, hi_i), n - 1)
    tt = t[idx]
    return (tt, out) if two_d else (tt[:, 0], out[:, 0])


# --------------------------------------------------------------------------- #
# Figures


@dataclass(frozen=True)
class Figure:
    """One figure of a page.

    Attributes:
        key: a short unique name (the div's id).
        caption: what it shows, one sentence.
        spec: the plotly document (``kind == "plot"``) or the leg-view spec (``kind == "leg"``).
        kind: ``"plot"`` or ``"leg"``.
    """

    key: str
    caption: str
    spec: Mapping[str, Any]
    kind: str = "plot"


def run_title(run: Run) -> str:
    """A run's name in page and figure titles: its scenario's name with the profile and contact mode (every run of
    one scenario alike: the reference-contact run read "effort__reference (matched profile, reference contact)"
    and the engine-defaults one "effort (engine-defaults profile, native contact)")."""
    return f"{run.name} ({run.profile} profile, {run.contact_mode} contact)"


def _run_styles(result: ComparisonResult) -> dict[str, tuple[str, str]]:
    """(colour, dash) of every backend of the run, its failed ones too, the same in every figure (a backend
    missing from one figure does not shift the colours of those after it)."""
    return _styles([*result.traces, *result.run.partial], result.reference)


def _styles(names: Sequence[str], reference: str) -> dict[str, tuple[str, str]]:
    """(colour, dash) per trace name: the reference black and solid, the others a palette colour and a dash."""
    out = {reference: ("#000000", "solid")}
    for n in names:
        if n not in out:
            i = len(out) - 1
            out[n] = (_PALETTE[i % len(_PALETTE)], _DASHES[i % len(_DASHES)])
    return out


def _axis(title: str, **extra: Any) -> dict[str, Any]:
    return {
        "title": {"text": title, "font": {"size": 11}},
        "showgrid": True,
        "gridcolor": "#e5e5e5",
        "zeroline": False,
        "exponentformat": "e",
        "hoverformat": ".6g",
        **extra,
    }


def _layout(title: str, rows: int, ylabels: Sequence[str], shared: bool = True, height: int = 0) -> dict[str, Any]:
    """Rows of subplots; with ``shared`` one time axis for all (zoom one, all follow)."""
    gap = 0.05 if shared else 0.1
    h = (1.0 - gap * (rows - 1)) / rows
    lay: dict[str, Any] = {
        "title": {"text": title, "font": {"size": 14}, "x": 0.01},
        "height": height or 170 * rows + 130,
        "margin": {"l": 80, "r": 20, "t": 50, "b": 45},
        "hovermode": "x unified" if shared else "closest",
        "legend": {"orientation": "h", "y": -0.08, "x": 0, "yanchor": "top", "font": {"size": 11}},
        "plot_bgcolor": "#ffffff",
        "font": {"family": "system-ui, sans-serif", "size": 11},
    }
    for r in range(rows):
        suffix = "" if r == 0 else str(r + 1)
        top = 1.0 - r * (h + gap)
        lay[f"yaxis{suffix}"] = _axis(ylabels[r], domain=[top - h, top], anchor=f"x{suffix}")
        xa = _axis("t [s]" if (r == rows - 1 or not shared) else "", anchor=f"y{suffix}", hoverformat=".4f")
        if shared and r > 0:
            xa["matches"] = "x"
        if shared and r < rows - 1:
            xa["showticklabels"] = False
        lay[f"xaxis{suffix}"] = xa
    return lay


def _events(lay: dict[str, Any], run: Run) -> None:
    """Controller switches: dashed lines across every row, named at the top."""
    shapes = [
        {
            "type": "line",
            "xref": "x",
            "yref": "paper",
            "x0": ev.t,
            "x1": ev.t,
            "y0": 0,
            "y1": 1,
            "line": {"color": "#8c8c8c", "width": 1, "dash": "dash"},
            "layer": "below",
        }
        for ev in run.events
    ]
    notes = [
        {
            "x": ev.t,
            "y": 1.0,
            "xref": "x",
            "yref": "paper",
            "text": ev.controller,
            "showarrow": False,
            "xanchor": "left",
            "yanchor": "bottom",
            "font": {"size": 10, "color": "#595959"},
        }
        for ev in run.events
    ]
    lay["shapes"] = lay.get("shapes", []) + shapes
    lay["annotations"] = lay.get("annotations", []) + notes


def _xrange(run: Run, traces: Mapping[str, RunResult]) -> list[float]:
    ends = [float(tr.t[-1]) for tr in traces.values() if len(tr.t)]
    hi = run.duration if math.isfinite(run.duration) else max(ends, default=1.0)
    return [0.0, float(max(hi, max(ends, default=hi)))]


def _trace(
    arrays: Arrays,
    x: np.ndarray,
    y: np.ndarray,
    row: int,
    name: str,
    color: str,
    dash: str,
    width: float,
    legend: bool,
    opacity: float = 1.0,
) -> dict[str, Any]:
    suffix = "" if row == 0 else str(row + 1)
    return {
        "type": "scatter",
        "mode": "lines",
        "x": arrays.ref(x),
        "y": arrays.ref(y),
        "name": name,
        "legendgroup": name,
        "showlegend": legend,
        "xaxis": f"x{suffix}",
        "yaxis": f"y{suffix}",
        "line": {"color": color, "width": width, "dash": dash},
        "opacity": opacity,
        # each trace's own sample time: the display envelopes sample each trace at its own times, so the shared
        # hover's one t could be a bin (7-24 ms) from a trace's point
        "hovertemplate": "%{y:.6g} at t = %{x:.4f} s",
    }


def no_ground_force(result: ComparisonResult) -> bool:
    """Every backend logged a ground force, and it is 0 at every sample: the foot never touched the ground (the
    position and ellipse tasks). Its overlay and deviation figures would be flat lines at 0: the run gets none,
    and its page says why."""
    traces = [tr for tr in (*result.traces.values(), *result.run.partial.values()) if len(tr.t)]
    return bool(traces) and all(tr.has("force") and not np.nan_to_num(tr.signal("force")).any() for tr in traces)


def _overlay(result: ComparisonResult, signal: str, arrays: Arrays) -> Figure | None:
    run = result.run
    shown = {**result.traces, **{f"{k} (failed)": v for k, v in run.partial.items()}}
    shown = {k: v for k, v in shown.items() if len(v.t)}
    if signal != "ee" and not any(tr.has(signal) for tr in shown.values()):
        return None
    if signal == "force" and no_ground_force(result):
        return None
    styles = _run_styles(result)
    comps = ("x", "y", "z") if signal == "ee" else JOINTS[signal]
    unit = UNITS[signal]
    data = []
    for name, tr in shown.items():
        base = name.removesuffix(" (failed)")
        color, dash = styles[base]
        is_ref = base == result.reference
        tt, yy = envelope(tr.t, tr.signal(signal))
        label = f"{name} (reference)" if is_ref else name
        for j in range(3):
            data.append(
                _trace(
                    arrays,
                    tt[:, j],
                    yy[:, j],
                    j,
                    label,
                    color,
                    "dot" if name != base else dash,
                    3.0 if is_ref else 1.5,
                    j == 0,
                    0.5 if is_ref else 0.95,
                )
            )
    ylabels = [f"{'ee_' + c if signal == 'ee' else column_label(signal, c)} [{unit}]" for c in comps]
    lay = _layout(f"{run_title(run)}: {NAMES[signal]}, every backend", 3, ylabels)
    lay["xaxis"]["range"] = _xrange(run, shown)
    _events(lay, run)
    return Figure(
        f"overlay-{signal}",
        f"Overlay of the {NAMES[signal]}, every backend, one row per component; "
        "zoom one row and the others follow; dashed lines are controller switches.",
        {"data": data, "layout": lay},
    )


def _pairs(result: ComparisonResult, signal: str) -> list[Any]:
    cols = np.arange(12)[SLICE[signal]]
    return [p for p in result.pairs if p.reference == result.reference and np.isfinite(p.deviation[:, cols]).any()]


def _deviation(result: ComparisonResult, signal: str, arrays: Arrays) -> Figure | None:
    run = result.run
    pairs = _pairs(result, signal)
    if not pairs or (signal == "force" and no_ground_force(result)):
        return None
    styles = _run_styles(result)
    cols = np.arange(12)[SLICE[signal]]
    unit = UNITS[signal]
    data = []
    for p in pairs:
        color, dash = styles[p.backend]
        lag = f", lag {p.lag_removed * 1e3:.3g} ms removed" if p.lag_removed else ""
        tt, yy = envelope(p.t, p.deviation[:, cols])
        for j in range(3):
            data.append(_trace(arrays, tt[:, j], yy[:, j], j, f"{p.backend}{lag}", color, dash, 1.4, j == 0))
    ylabels = [f"\u0394{column_label(signal, c)} [{unit}]" for c in JOINTS[signal]]
    lay = _layout(f"{run_title(run)}: {NAMES[signal]}, deviation from {result.reference}", 3, ylabels)
    lay["xaxis"]["range"] = _xrange(run, result.traces)
    if run.skip > 0:
        lay["shapes"] = [
            {
                "type": "rect",
                "xref": "x",
                "yref": "paper",
                "x0": 0,
                "x1": run.skip,
                "y0": 0,
                "y1": 1,
                "fillcolor": "#ebebeb",
                "line": {"width": 0},
                "layer": "below",
            }
        ]
    _events(lay, run)
    return Figure(
        f"deviation-{signal}",
        f"Deviation of the {NAMES[signal]} from {result.reference} (x - x_ref), "
        "min/max envelope of every bin so short transients keep their height.",
        {"data": data, "layout": lay},
    )


def _focus_transients(result: ComparisonResult, arrays: Arrays) -> Figure | None:
    """Each signal's largest deviation (over backends and components) at full resolution, in a window around it."""
    rows: list[tuple[str, int, float]] = []  # (signal, column, time)
    for s in SIGNALS:
        best: tuple[float, int, float] | None = None
        for p in _pairs(result, s):
            for c in np.arange(12)[SLICE[s]]:
                m, tm = float(p.max_abs[c]), float(p.t_max_abs[c])
                if math.isfinite(m) and math.isfinite(tm) and (best is None or m > best[0]):
                    best = (m, int(c), tm)
        if best is not None and best[0] > 0:
            rows.append((s, best[1], best[2]))
    if not rows:
        return None
    styles = _run_styles(result)
    data, ylabels = [], []
    for r, (s, c, tm) in enumerate(rows):
        for p in _pairs(result, s):
            k0, k1 = np.searchsorted(p.t, [tm - FOCUS_HALF_WIDTH, tm + FOCUS_HALF_WIDTH])
            if k1 - k0 < 2:
                continue
            color, dash = styles[p.backend]
            data.append(_trace(arrays, p.t[k0:k1], p.deviation[k0:k1, c], r, p.backend, color, dash, 1.4, r == 0))
        lab = column_label(s, JOINTS[s][c - SLICE[s].start])
        ylabels.append(f"\u0394{lab} [{UNITS[s]}]")
    title = f"{run_title(result.run)}: the largest deviations at full resolution"
    lay = _layout(title, len(rows), ylabels, shared=False)
    for r, (_, _, tm) in enumerate(rows):
        lay["xaxis" if r == 0 else f"xaxis{r + 1}"]["title"]["text"] = f"t [s] (around {tm:.4f} s)"
    return Figure(
        "focus-transients",
        f"Focus on transients: for each signal the component with the largest "
        f"deviation, every sample within {FOCUS_HALF_WIDTH * 1e3:g} ms of its peak.",
        {"data": data, "layout": lay},
    )


def _focus_steady(result: ComparisonResult, arrays: Arrays) -> Figure | None:
    """Joint-angle deviation over the steady window, every sample: the small steady-state differences."""
    run = result.run
    pairs = _pairs(result, "q")
    if not pairs or not run.steady_window > 0:
        return None
    styles = _run_styles(result)
    data = []
    for p in pairs:
        k0 = int(np.searchsorted(p.t, p.t[-1] - run.steady_window))
        color, dash = styles[p.backend]
        for j in range(3):
            data.append(_trace(arrays, p.t[k0:], p.deviation[k0:, j], j, p.backend, color, dash, 1.4, j == 0))
    ylabels = [f"\u0394{column_label('q', c)} [rad]" for c in JOINTS["q"]]
    lay = _layout(f"{run_title(run)}: joint-angle deviation over the steady window", 3, ylabels)
    return Figure(
        "focus-steady",
        f"Focus on the steady state: deviation of q from {result.reference} over the "
        f"final {run.steady_window:g} s, every sample, each row on its own scale.",
        {"data": data, "layout": lay},
    )


def _leg_view(result: ComparisonResult, arrays: Arrays) -> Figure | None:
    """The leg of every backend in W, one pose per slider step, with each foot's path and the ground plane; None
    when the run used another leg model than the active one (:func:`model_match`), whose geometry it would draw."""
    run = result.run
    match = model_match(run)
    if match.differs:  # the kinematics would draw the active model's leg, not the one that ran
        return None
    shown = {k: v for k, v in {**result.traces, **run.partial}.items() if len(v.t) and np.isfinite(v.q).all()}
    if not shown:
        return None
    styles = _run_styles(result)
    t_end = max(float(tr.t[-1]) for tr in shown.values())
    times = np.linspace(0.0, t_end, LEG_FRAMES)
    backends: list[dict[str, Any]] = []
    static: list[dict[str, Any]] = []
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for name, tr in shown.items():
        k = np.clip(np.searchsorted(tr.t, times), 0, len(tr.t) - 1)
        pts = kinematics.chain(tr.q[k])  # (frames, 5, 3) in W [m]
        lo, hi = np.minimum(lo, pts.min(axis=(0, 1))), np.maximum(hi, pts.max(axis=(0, 1)))
        color = styles[name][0]
        label = f"{name} (reference)" if name == result.reference else name
        width = max(3, 11 - 2 * len(backends))  # thinner for each later backend, so coinciding legs stay visible
        backends.append({"name": label, "color": color, "width": width, "points": arrays.ref(pts.ravel())})
        foot = kinematics.fk(tr.q[:: max(1, len(tr.t) // 1000)])
        static.append(
            {
                "type": "scatter3d",
                "mode": "lines",
                "name": f"{name} foot path",
                "legendgroup": label,
                "showlegend": False,
                "x": arrays.ref(foot[:, 0]),
                "y": arrays.ref(foot[:, 1]),
                "z": arrays.ref(foot[:, 2]),
                "line": {"color": color, "width": 2},
                "opacity": 0.5,
            }
        )
    pad = 0.05
    x0, x1 = float(lo[0] - pad), float(hi[0] + pad)
    y0, y1 = float(lo[1] - pad), float(hi[1] + pad)
    static.insert(
        0,
        {
            "type": "mesh3d",
            "name": "ground (z = 0)",
            "x": [x0, x1, x1, x0],
            "y": [y0, y0, y1, y1],
            "z": [0, 0, 0, 0],
            "i": [0, 0],
            "j": [1, 2],
            "k": [2, 3],
            "color": "#c8b99a",
            "opacity": 0.5,
            "hoverinfo": "skip",
            "showlegend": True,
        },
    )
    z1 = float(max(hi[2], 0.0) + pad)
    span = max(x1 - x0, y1 - y0, z1)
    scene = {
        "xaxis": {"title": {"text": "x [m]"}, "range": [x0, x1]},
        "yaxis": {"title": {"text": "y [m]"}, "range": [y0, y1]},
        "zaxis": {"title": {"text": "z [m]"}, "range": [-0.02, z1]},
        "aspectmode": "manual",
        "aspectratio": {"x": (x1 - x0) / span, "y": (y1 - y0) / span, "z": z1 / span},
        "camera": {"eye": {"x": 1.25, "y": -1.25, "z": 0.7}},
    }
    layout = {
        "title": {"text": f"{run_title(run)}: the leg of every backend (W)", "font": {"size": 14}, "x": 0.01},
        "height": 620,
        "margin": {"l": 0, "r": 0, "t": 40, "b": 0},
        "scene": scene,
        "legend": {"orientation": "h", "y": 0.02},
        "uirevision": "leg",
    }
    # the foot marker's size in pixels stands for the foot sphere; only a visual cue
    spec = {
        "times": [round(float(x), 6) for x in times],
        "backends": backends,
        "static": static,
        "layout": layout,
        "foot_size": 9,
    }
    return Figure(
        "leg",
        "The leg of every backend, drawn from its logged joint angles through the forward "
        "kinematics in W (the base point, ab/ad, hip, knee, foot centre); thin lines are each foot's path, the "
        "plane is the ground. Drag the slider or press play; drag the view to turn it."
        + (
            ""
            if match.run is not None
            else f" run.json does not name the leg model of the run: drawn with the active one ({match.active})."
        ),
        spec,
        "leg",
    )


def run_figures(result: ComparisonResult, arrays: Arrays) -> list[Figure]:
    """Every figure of a run report, in page order (overlays, deviations, focused views, the 3D leg)."""
    out: list[Figure | None] = [_overlay(result, s, arrays) for s in (*SIGNALS, "ee")]
    out += [_deviation(result, s, arrays) for s in SIGNALS]
    out += [_focus_transients(result, arrays), _focus_steady(result, arrays), _leg_view(result, arrays)]
    return [f for f in out if f is not None]
