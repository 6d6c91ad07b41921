"""One look for every report page (a run's report.html, campaign.html, robustness.html): the shared
layout and styles, and the first screen's parts: a title that names the task, a verdict, the key
figures each beside its goal with a pass mark, the command that reproduces the run, a picture.
Self-contained HTML: figures are embedded PNG data, no network resources."""

from __future__ import annotations

import html
from dataclasses import dataclass

STYLE = """
body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;max-width:1220px;margin:0.8em auto;color:#222;
 padding:0 1em}
h1{font-size:1.45em;margin:0.2em 0 0.3em} h2{font-size:1.15em;margin:1.2em 0 0.4em}
.verdict{padding:0.45em 0.8em;border-radius:4px;font-weight:600;margin:0.3em 0 0.7em}
.verdict.ok{background:#e4f4e4;border-left:6px solid #2a8a2a}
.verdict.fail{background:#fbe4e4;border-left:6px solid #b22}
.verdict.info{background:#eceef8;border-left:6px solid #667}
.first{display:flex;gap:1.4em;align-items:flex-start} .first>div{flex:1 1 0;min-width:0}
table{border-collapse:collapse;margin:0.3em 0} th,td{border:1px solid #ccc;padding:2px 7px;font-size:88%;
 text-align:left;vertical-align:top}
td.num{text-align:right;white-space:nowrap} .pass{color:#2a8a2a;font-weight:700} .miss{color:#b22;font-weight:700}
.key{color:#888;font-family:monospace;font-size:82%}
code.cmd{display:block;background:#f3f3f3;padding:0.35em 0.5em;white-space:pre-wrap;word-break:break-all;
 font-size:82%}
img{max-width:100%} .picture img{max-height:420px;display:block;margin-bottom:0.4em}
.picture figcaption{font-size:82%;color:#555;margin-bottom:0.6em}
details>summary{cursor:pointer}
"""


@dataclass(frozen=True)
class KeyFigure:
    """One of a report's key figures: its human name, its value with its unit, its goal or limit
    (empty: none), whether it meets it (None: no goal) and the report.json key it comes from."""

    name: str
    value: str
    goal: str = ""
    ok: bool | None = None
    key: str = ""


@dataclass(frozen=True)
class Verdict:
    """Did the run do its task: ``ok`` (None: a run with no task to judge) and why, in one line."""

    ok: bool | None
    text: str


@dataclass(frozen=True)
class Summary:
    """What a report's first screen answers: the task and its parameters, the verdict, the key figures."""

    title: str
    verdict: Verdict
    figures: tuple[KeyFigure, ...]


def page(title: str, body: str) -> str:
    """A whole self-contained page in the shared look."""
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
            f"<style>{STYLE}</style></head><body>\n{body}\n</body></html>\n")


def first_screen(summary: Summary, command: str | None = None, pictures: list[tuple[str, str]] = ()) -> str:
    """The title, the verdict, the key figures with the command under them and, beside them, the
    pictures (caption, PNG as base64)."""
    verdict = summary.verdict
    kind = "info" if verdict.ok is None else "ok" if verdict.ok else "fail"
    rows = "".join(_figure_row(f) for f in summary.figures)
    table = (f"<table><tr><th>figure</th><th>value</th><th>goal or limit</th><th></th></tr>{rows}</table>"
             if rows else "")
    reproduce = ("" if command is None else
                 f'<p style="margin:0.6em 0 0.2em">Reproduce:</p><code class="cmd">{html.escape(command)}</code>')
    images = "".join(f'<figure class="picture" style="margin:0"><img alt="{html.escape(c)}" '
                     f'src="data:image/png;base64,{png}"><figcaption>{html.escape(c)}</figcaption></figure>'
                     for c, png in pictures)
    side = f"<div>{images}</div>" if images else ""
    return (f"<h1>{html.escape(summary.title)}</h1>"
            f'<div class="verdict {kind}">{html.escape(verdict.text)}</div>'
            f'<div class="first"><div>{table}{reproduce}</div>{side}</div>')


def figure_section(title: str, png: str) -> str:
    """A figure below the first screen: its title, then the image."""
    return f'<h2>{html.escape(title)}</h2><img alt="{html.escape(title)}" src="data:image/png;base64,{png}">'


def _figure_row(f: KeyFigure) -> str:
    mark = "" if f.ok is None else '<span class="pass">✓</span>' if f.ok else '<span class="miss">✗</span>'
    key = f' <span class="key">{html.escape(f.key)}</span>' if f.key else ""
    return (f"<tr><td>{html.escape(f.name)}{key}</td><td class=\"num\">{html.escape(f.value)}</td>"
            f"<td>{html.escape(f.goal)}</td><td>{mark}</td></tr>")
