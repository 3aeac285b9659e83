"""The HTML report: one self-contained file (plotly.js inline, works offline).

Per capture its devices and timeline; per device one figure whose rows share
the time axis: the states (BU/RU state, MC-MB2-PN status per slot) as steps,
the findings as coloured markers, the watchdog ages against their limits, and
the joysticks where present. Only this output needs plotly.
"""
import gzip
import html as H
import re
from pathlib import Path

import plotly.graph_objects as go
from plotly.offline import get_plotlyjs, get_plotlyjs_version
from plotly.subplots import make_subplots

from . import health, held
from .expect import listed, title
from .text import device

# plotly.js's "basic" bundle (scatter, bar, pie; npm plotly.js-basic-dist-min,
# MIT, plotly-basic.LICENSE): every plot here is a scatter trace with shapes,
# and the page is a quarter of the size with it. Used when it is the
# plotly.js version the installed plotly writes figures for.
BASIC_BUNDLE = Path(__file__).resolve().with_name("plotly-basic.min.js.gz")

COLOURS = {"note": "#3b78b0", "warning": "#e08a00", "error": "#c62828"}
SHADED = ("relays", "stall", "gap", "poll_gap", "stopped")  # shaded over their span in the plots
SEVERITY_Y = {"note": 1, "warning": 2, "error": 3}
TIMELINE_ROWS = 3000  # timeline lines per capture in the page (all are in --json)
PALETTE = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22"]

CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.25em; margin-top: 2em; border-bottom: 1px solid #ccc; }
h3 { font-size: 1.05em; margin-top: 1.5em; }
table { border-collapse: collapse; font-size: 0.9em; }
td, th { padding: 2px 8px; text-align: left; vertical-align: top; border-bottom: 1px solid #eee; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.sev { font-weight: bold; } .note { color: #3b78b0; } .warning { color: #e08a00; } .error { color: #c62828; }
.error-line { color: #c62828; font-weight: bold; }
.muted { color: #777; }
"""


def ordinal(values, labels):
    """Map state values to evenly spaced rows, known labels first: (map, tickvals, ticktext)."""
    known = sorted(int(k) for k in labels)
    extra = sorted(v for v in set(values) if v not in known)
    order = known + extra
    pos = {v: i for i, v in enumerate(order)}
    text = [labels.get(str(v), "0x%02X" % v) for v in order]
    return pos, list(range(len(order))), text


def states(values):
    return ", ".join("%s %s" % kv for kv in values.items())


def last_states(dev):
    """The states at the end, as the text's "last:" line gives them."""
    if dev["final"] == dev["initial"]:
        return "as first" if dev["final"] else ""
    return states(dev["final"])


def plot_rows(dev, timeline):
    """The figure's rows: (title, kind, traces), top to bottom."""
    rows, states = [], {}
    for name, s in dev["series"].items():
        if s["group"] == "state":
            key = tuple(sorted(s.get("labels", {}).items()))
            states.setdefault(key, []).append((name, s))
    for group in states.values():
        title = group[0][0] if len(group) == 1 else "%s .. %s" % (group[0][0], group[-1][0])
        rows.append((title, "state", group))
    if timeline:
        rows.append(("findings", "findings", timeline))
    ages = [(n, s) for n, s in dev["series"].items() if s["group"] == "age"]
    if ages:
        rows.append(("ages against their limits (s)", "age", ages))
    values = [(n, s) for n, s in dev["series"].items() if s["group"] == "value"]
    if values:
        rows.append(("joysticks", "value", values))
    return rows


def figure(dev, timeline, t_end):
    rows = plot_rows(dev, timeline)
    if not rows:
        return None
    heights = [0.6 if kind == "findings" else 1.0 for _, kind, _ in rows]
    fig = make_subplots(rows=len(rows), cols=1, shared_xaxes=True, vertical_spacing=0.045,
                        subplot_titles=[title for title, _, _ in rows], row_heights=heights)
    colour = 0
    for r, (title, kind, items) in enumerate(rows, start=1):
        if kind == "findings":
            for sev in ("note", "warning", "error"):
                picked = [e for e in items if e["severity"] == sev]
                if picked:
                    fig.add_trace(go.Scatter(
                        x=[e["time"] for e in picked], y=[SEVERITY_Y[sev]] * len(picked),
                        mode="markers", name=sev, legendgroup="findings",
                        marker=dict(color=COLOURS[sev], size=10, symbol="diamond"),
                        text=["frame %d: %s" % (e["frame"], e["text"]) for e in picked],
                        hovertemplate="%{x:.3f} s %{text}<extra></extra>"), row=r, col=1)
            fig.update_yaxes(tickvals=[1, 2, 3], ticktext=["note", "warning", "error"],
                             range=[0.5, 3.5], row=r, col=1)
            continue
        if kind == "state":
            labels = items[0][1].get("labels", {})
            pos, tickvals, ticktext = ordinal([v for _, s in items for v in s["v"]], labels)
            fig.update_yaxes(tickvals=tickvals, ticktext=ticktext,
                             range=[-0.5, len(tickvals) - 0.5], row=r, col=1)
        for name, s in items:
            c = PALETTE[colour % len(PALETTE)]
            colour += 1
            y = [pos[v] for v in s["v"]] if kind == "state" else s["v"]
            hover = ([labels.get(str(v), "0x%02X" % v) for v in s["v"]] if kind == "state"
                     else None)
            shape = "hv" if kind == "state" else "linear"
            fig.add_trace(go.Scatter(
                x=s["t"], y=y, name=name, mode="lines", line=dict(color=c, width=2, shape=shape),
                text=hover, hovertemplate="%{x:.3f} s " + ("%{text}" if hover else "%{y}")
                + "<extra>" + H.escape(name) + "</extra>"), row=r, col=1)
            if kind == "age" and s.get("limit") is not None:
                fig.add_trace(go.Scatter(
                    x=[0, t_end], y=[s["limit"], s["limit"]], mode="lines", name=name + " limit",
                    line=dict(color=c, width=1, dash="dash"), hoverinfo="skip"), row=r, col=1)
    for e in timeline:  # conditions with a length: shaded across all rows
        if e["kind"] in SHADED and e["duration"]:
            fig.add_vrect(x0=e["end_time"] - e["duration"], x1=e["end_time"], line_width=0,
                          fillcolor=COLOURS[e["severity"]], opacity=0.15, layer="below")
    fig.update_xaxes(range=[0, max(t_end, 0.001)])
    fig.update_xaxes(title_text="seconds from the first frame", row=len(rows), col=1)
    fig.update_layout(height=110 + 170 * sum(heights), margin=dict(l=60, r=20, t=40, b=40),
                      template="plotly_white", legend=dict(orientation="v"))
    return fig


def figure_div(fig, div_id):
    """The figure's <div> and script, the div named div_id."""
    config = {"displaylogo": False, "responsive": True}
    try:
        return fig.to_html(full_html=False, include_plotlyjs=False, div_id=div_id, config=config)
    except TypeError:
        # plotly before 5.5 (Debian 12's python3-plotly is 5.4) names the div itself
        out = fig.to_html(full_html=False, include_plotlyjs=False, config=config)
        return out.replace(re.search(r'<div id="([^"]+)"', out).group(1), div_id)


def capture_section(index, rep, plotted=lambda: None):
    out = ['<h2>%s</h2>' % H.escape(rep["capture"])]
    if rep["error"]:
        out.append('<p class="error-line">%s</p>' % H.escape(rep["error"]))
    if rep.get("missing"):
        out.append('<p class="error-line">expected %s, none found</p>'
                   % H.escape(listed([title(n) for n in rep["missing"]])))
    if rep["frames"] == 0:
        return "\n".join(out)
    out.append("<p>%d frames, %.3f s from %s</p>" % (rep["frames"], rep["duration"],
                                                     H.escape(rep["start"] or "")))
    if held.cut(rep):
        out.append("<p>%s: what they do not hold is not captured.</p>" % H.escape(held.cut(rep)))
    if not rep["devices"]:
        out += ["<p>%s.</p>" % H.escape(line[0].upper() + line[1:]) for line in held.no_device(rep)]
        if not rep["timeline"]:
            return "\n".join(out)
    else:
        out.append(devices_table(rep))
        out.append(health_table(rep))
    for d in rep["devices"]:
        timeline = [e for e in rep["timeline"] if e["device"] == d["id"]]
        fig = figure(d, timeline, rep["duration"])
        out.append("<h3>[%d] %s</h3>" % (d["id"], H.escape(d["name"])))
        if fig is not None:
            out.append(figure_div(fig, "plot-%d-%d" % (index, d["id"])))
        plotted()
    out.append("<h3>Timeline</h3>")
    if not rep["timeline"]:
        out.append("<p>No state change and no finding.</p>")
        return "\n".join(out)
    out.append('<table><tr><th>time (s)</th><th>frame</th><th>severity</th><th>device</th>'
               '<th>what</th></tr>')
    for e in rep["timeline"][:TIMELINE_ROWS]:
        out.append('<tr><td class=num>%.3f</td><td class=num>%d</td><td class="sev %s">%s</td>'
                   '<td>%s</td><td>%s</td></tr>' % (e["time"], e["frame"], e["severity"],
                                                    e["severity"], device(e), H.escape(e["text"])))
    out.append("</table>")
    if len(rep["timeline"]) > TIMELINE_ROWS:
        out.append('<p class="muted">%d more entries: see the text or JSON report.</p>'
                   % (len(rep["timeline"]) - TIMELINE_ROWS))
    return "\n".join(out)


def devices_table(rep):
    out = ["<table><tr><th>#</th><th>device</th><th>frames</th><th>time</th>"
           "<th>layout</th><th>first state</th><th>last state</th><th>terminals</th></tr>"]
    for d in rep["devices"]:
        terms = ", ".join("%d (frames %d-%d)" % (t["terminal"], t["first_frame"], t["last_frame"])
                          for t in d.get("terminals", []))
        out.append("<tr><td>%d</td><td>%s</td><td class=num>%d (%d-%d)</td>"
                   "<td class=num>%.3f-%.3f s</td><td>%s</td><td>%s</td><td>%s</td><td>%s</td></tr>" % (
                       d["id"], H.escape(d["name"]), d["frames"], d["first_frame"], d["last_frame"],
                       d["start"], d["end"], H.escape(d["layout"] or ""),
                       H.escape(states(d["initial"])), H.escape(last_states(d)), H.escape(terms)))
    out.append("</table>")
    return "\n".join(out)


def health_table(rep):
    """The health rows (health.py): a row per stream of each device."""
    rows = [(d["id"], row) for d in rep["devices"] for row in d.get("streams", [])]
    if not rows:
        return ""
    out = ["<h3>Health</h3>", "<table><tr><th>#</th>%s</tr>" % "".join(
        "<th>%s</th>" % H.escape(h) for h in health.HEADER)]
    for ident, row in rows:
        cells = health.cells(row)
        out.append("<tr><td>%d</td><td>%s</td>%s</tr>" % (
            ident, H.escape(cells[0]), "".join(
                "<td%s>%s</td>" % ("" if i == 3 else " class=num", H.escape(c))
                for i, c in enumerate(cells[1:], 1))))
    out.append("</table>")
    return "\n".join(out)


def plotly_js():
    """The plotly.js to inline: the basic bundle, else plotly's full one
    (the one the installed plotly writes figures for), else the basic bundle
    all the same (a plotly packaged without its plotly.js)."""
    try:
        with gzip.open(BASIC_BUNDLE, "rt", encoding="utf-8") as f:
            js = f.read()
    except OSError:
        return get_plotlyjs()
    version = re.search(r"plotly\.js \(basic - minified\) v(\S+)", js[:500])
    if version and version.group(1) == get_plotlyjs_version():
        return js
    try:
        return get_plotlyjs()
    except OSError:
        return js


def document(reports, progress=None):
    """The page; progress(done, total) after each device's figure (the slow part)."""
    total = sum(len(rep["devices"]) for rep in reports if rep["frames"]) or 1
    done = [0]

    def plotted():
        done[0] += 1
        if progress:
            progress(done[0], total)
    body = "\n".join(capture_section(i, rep, plotted) for i, rep in enumerate(reports, start=1))
    names = ", ".join(H.escape(rep["capture"]) for rep in reports)
    return ("<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8>"
            "<title>vrshark report: %s</title><style>%s</style>"
            "<script>%s</script></head><body>"
            "<h1>vrshark report</h1><p class=muted>Frame numbers open in Wireshark with "
            "<code>wireshark -r CAPTURE -g FRAME</code>.</p>\n%s\n</body></html>\n"
            % (names, CSS, plotly_js(), body))


def write(page, path):
    with open(path, "w", encoding="utf-8") as f:
        f.write(page)
