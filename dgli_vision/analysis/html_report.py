"""One self-contained HTML page beside an evaluation's ``report.md``.

The page holds the summary (right, "cannot tell", wrong, unreadable), the confusion
picture, the risk-coverage curve (drawn inline as SVG: how accurate the answers are as
the confidence threshold is raised, against the share of pairs still answered) and a
gallery of the wrong and "cannot tell" pairs with their overlays and reasons. Images are
referenced by relative path (they sit in the report folder); nothing is fetched.
"""

from __future__ import annotations

from collections.abc import Callable
from html import escape
from typing import Any

import numpy as np

__all__ = ["evaluation_html", "risk_coverage"]

_STYLE = (
    "body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}"
    "figure{display:inline-block;width:340px;margin:8px;vertical-align:top}"
    "figure img{width:100%;border:1px solid #ccc}figcaption{font-size:13px}"
    "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px}"
)


def risk_coverage(outcomes: list[Any]) -> list[tuple[float, float, float]]:
    """(threshold, coverage, accuracy of the answers) at each confidence of the answers
    given: raising the threshold to it keeps the answers at or above it.

    Parameters
    ----------
    outcomes : list of PairOutcome
        Coverage is over the pairs read; a pair answered "cannot tell" is never
        answered at any threshold.
    """
    read = [o for o in outcomes if o.error is None]
    answered = [o for o in read if o.predicted is not None and o.confidence is not None]
    if not answered:
        return []
    conf = np.array([o.confidence for o in answered], dtype=float)
    right = np.array([o.correct for o in answered], dtype=bool)
    out = []
    for t in sorted(set(conf.tolist())):
        take = conf >= t
        out.append((float(t), float(take.sum() / len(read)), float(right[take].mean())))
    return out


def _curve_svg(points: list[tuple[float, float, float]]) -> str:
    """The risk-coverage curve as inline SVG (x: coverage, y: accuracy of answers)."""
    w, h, pad = 420, 260, 40
    if not points:
        return "<p>No best guesses to draw.</p>"

    def xy(cov: float, acc: float) -> str:
        return f"{pad + cov * (w - 2 * pad):.1f},{h - pad - acc * (h - 2 * pad):.1f}"

    line = " ".join(xy(c, a) for _, c, a in sorted(points, key=lambda p: p[1]))
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}">'
        f'<rect width="{w}" height="{h}" fill="white"/>'
        f'<line x1="{pad}" y1="{h - pad}" x2="{w - pad}" y2="{h - pad}" stroke="black"/>'
        f'<line x1="{pad}" y1="{pad}" x2="{pad}" y2="{h - pad}" stroke="black"/>'
        f'<polyline points="{line}" fill="none" stroke="#1f77b4" stroke-width="2"/>'
        f'<text x="{w / 2 - 60}" y="{h - 8}" font-size="12">share of pairs answered</text>'
        f'<text x="4" y="{pad - 10}" font-size="12">accuracy of the answers (0-1)</text>'
        "</svg>"
    )


def _figure(src: str, caption: str) -> str:
    return (
        f'<figure><a href="{escape(src)}"><img src="{escape(src)}" alt="overlay"></a>'
        f"<figcaption>{escape(caption)}</figcaption></figure>"
    )


def evaluation_html(
    result: Any, meta: dict[str, Any], overlay_of: Callable[[Any], str], name: Callable
) -> str:
    """The HTML page of an evaluation report.

    Parameters
    ----------
    result : EvaluationResult
    meta : dict
        ``command``, ``references``, ``package_version``.
    overlay_of : callable
        ``overlay_of(outcome)`` -> the overlay's path relative to the report folder.
    name : callable
        ``name(class_id)`` -> ``"02 corner-over"``.
    """
    outs = result.outcomes
    wrong = [o for o in outs if o.predicted is not None and not o.correct]
    told = [o for o in outs if o.error is None and o.predicted is None]
    unread = [o for o in outs if o.error is not None]
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        "<title>dgli evaluate report</title>",
        f"<style>{_STYLE}</style></head><body>",
        "<h1>dgli evaluate report</h1>",
        "<ul>",
        f"<li>pairs: <b>{result.n}</b></li>",
        f"<li>answers: {escape(result.outcomes_text())}</li>",
        f"<li>class accuracy over all pairs: {result.accuracy:.2%}; variant accuracy: "
        f"{escape(result.variant_accuracy_text())}</li>",
        f"<li>command: <code>{escape(str(meta.get('command', '')))}</code></li>",
        f"<li>references: <code>{escape(str(meta.get('references', '')))}</code>, "
        f"dgli_vision {escape(str(meta.get('package_version', '')))}</li>",
        "</ul>",
        "<h2>Confusion</h2>",
        '<img src="confusion.png" alt="confusion matrix" style="max-width:600px">',
        "<h2>Risk and coverage</h2>",
        "<p>Raising the confidence threshold answers fewer pairs, more of them right.</p>",
        _curve_svg(risk_coverage(outs)),
        f"<h2>Wrong ({len(wrong)})</h2>",
        *[
            _figure(overlay_of(o), f"{o.pair.color}: true {name(o.pair.label)}, "
                    f"predicted {name(o.predicted)}")
            for o in wrong
        ],
        f"<h2>Cannot tell ({len(told)})</h2>",
        *[
            _figure(overlay_of(o), f"{o.pair.color}: true {name(o.pair.label)}; {o.reason}")
            for o in told
        ],
        f"<h2>Not read ({len(unread)})</h2>",
        "<ul>",
        *[f"<li>{escape(o.pair.color)}: {escape(o.error or '')}</li>" for o in unread],
        "</ul>",
        "</body></html>",
    ]
    return "\n".join(parts) + "\n"
