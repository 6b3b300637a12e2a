"""HTML pieces of the results page and its sections: escaping, numbers, tables, anchors."""
from __future__ import annotations

import html
import math
import re
from typing import Any, Sequence

CSS = """
body{font-family:DejaVu Sans,Helvetica,Arial,sans-serif;margin:1.5em auto;max-width:1100px;color:#222;
line-height:1.35;padding:0 1em}
h1{font-size:1.5em}h2{font-size:1.25em;border-bottom:1px solid #ccc;margin-top:2em}h3{font-size:1.05em}
table{border-collapse:collapse;font-size:.85em;margin:.4em 0 1em}
td,th{border:1px solid #ddd;padding:2px 6px;text-align:left;vertical-align:top}
th{background:#f3f3f3}td.num{text-align:right;font-variant-numeric:tabular-nums}
.ok{background:#e8f5e9}.skipped,.stopped{background:#f5f5f5;color:#666}.diverged{background:#fff3e0}
.failed,.timeout{background:#ffebee}.lost{background:#fce4ec;color:#880e4f;font-weight:bold}
.undetermined{background:#fff8e1}.flag{color:#b71c1c;font-weight:bold}
figure{margin:.5em 0}figure svg,figure img{max-width:100%;height:auto}figcaption{font-size:.85em;color:#555}
.meta td:first-child{font-weight:bold}.note{font-size:.85em;color:#555}
nav a{margin-right:.8em}nav{line-height:1.7}
.lead{font-size:1em}.answer{font-size:1.05em;background:#f1f8e9;border-left:4px solid #7cb342;padding:.3em .6em}
details{margin:.3em 0}details>summary{cursor:pointer;color:#1a4f8b}details[open]>summary{font-weight:bold}
td.undetermined details{margin:0}td.undetermined summary{color:#6d4c00}td.law{cursor:help}
table.capabilities{font-size:.75em}table.capabilities td.cap{text-align:center;padding:1px 3px}
th.rot{vertical-align:bottom;padding:4px 2px}th.rot span{writing-mode:vertical-rl;transform:rotate(180deg);
white-space:nowrap}
h3{margin-top:1.4em}.footer{margin-top:2em}
"""

# records errors and checks that every figure's file loads and has a drawn size (a probe image
# per figure, so that lazy figures below the first screen are checked too); a browser test
# reads the result from <body data-figures="..." data-rendered="..." data-errors="...">
# (no network, no external script)
SCRIPT = """
(function(){var errs=[];
window.addEventListener('error',function(e){errs.push(String(e.message));document.body.dataset.errors=errs.join('|');});
window.addEventListener('load',function(){var figs=document.querySelectorAll('figure.plot');var drawn=0;
var left=figs.length;function done(){document.body.dataset.figures=figs.length;document.body.dataset.rendered=drawn;
document.body.dataset.errors=errs.join('|');}
if(!left){done();}
figs.forEach(function(f){var i=f.querySelector('img');if(!i){if(--left===0){done();}return;}
var probe=new Image();probe.onload=function(){if(probe.naturalWidth>50&&probe.naturalHeight>50&&i.width>50){drawn++;
f.dataset.rendered='yes';}if(--left===0){done();}};
probe.onerror=function(){errs.push('no figure '+i.getAttribute('src'));if(--left===0){done();}};
probe.src=i.src;});});})();
"""


def escape(x: Any) -> str:
    return html.escape("" if x is None else str(x))


def num(x, digits: int = 3) -> str:
    return f"{x:.{digits}g}" if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) else "-"


def table(header: Sequence[str], body: list[Sequence[str]], raw: bool = False) -> str:
    head = "".join(f"<th>{escape(h)}</th>" for h in header)
    rows = "".join("<tr>" + "".join(c if raw else f"<td>{escape(c)}</td>" for c in r) + "</tr>" for r in body)
    return f"<table><tr>{head}</tr>{rows}</table>"


def slug(name: str) -> str:
    return re.sub(r"[^a-z0-9-]", "-", name.lower())
