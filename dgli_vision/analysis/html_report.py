"""Self-contained HTML pages beside the Markdown reports (evaluate, track, robustness,
compare), built from a few shared pieces.

Every page is one file: the style is inline, pictures are referenced by a path relative
to the report folder (they sit in it); charts are SVG files (Matplotlib's) linking to
the same chart as PNG; nothing is fetched.
:func:`html_page` wraps the body; :func:`html_table`, :func:`html_list`,
:func:`html_chart`, :func:`html_gallery` and :func:`outcomes_html` build its parts.
Text is escaped here; the pieces return HTML.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from html import escape
from typing import Any

import numpy as np

__all__ = [
    "cannot_tell_text",
    "evaluation_html",
    "html_chart",
    "html_gallery",
    "html_list",
    "html_page",
    "html_table",
    "outcomes_html",
    "risk_coverage",
]

_STYLE = (
    "body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}"
    "figure{display:inline-block;width:340px;margin:8px;vertical-align:top}"
    "figure img{width:100%;border:1px solid #ccc}figcaption{font-size:13px}"
    "table{border-collapse:collapse;margin:0.5em 0}"
    "td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}"
    "img.wide{max-width:100%}p.note{font-size:13px;color:#555}"
)


def cannot_tell_text(reason: str | None) -> str:
    """``"cannot tell: <why>"``, without saying "cannot tell" twice when the reason
    already starts with it."""
    text = reason or "no reason given"
    return text if text.startswith("cannot tell") else f"cannot tell: {text}"


def html_page(title: str, body: Sequence[str]) -> str:
    """A whole HTML page: ``title`` as its title and first heading, then ``body`` (HTML
    parts, joined by new lines)."""
    return "\n".join(
        [
            "<!DOCTYPE html>",
            '<html lang="en"><head><meta charset="utf-8">',
            f"<title>{escape(title)}</title>",
            f"<style>{_STYLE}</style></head><body>",
            f"<h1>{escape(title)}</h1>",
            *body,
            "</body></html>",
        ]
    ) + "\n"


def html_list(items: Sequence[str], *, raw: bool = False) -> str:
    """A bulleted list of ``items`` (text, escaped; HTML when ``raw``)."""
    cells = items if raw else [escape(str(i)) for i in items]
    return "<ul>" + "".join(f"<li>{c}</li>" for c in cells) + "</ul>"


def html_table(header: Sequence[object], rows: Sequence[Sequence[object]]) -> str:
    """A table of text cells (escaped; a float in four significant digits)."""

    def cell(v: object) -> str:
        return escape(f"{v:.4g}" if isinstance(v, float) else str(v))

    head = "".join(f"<th>{cell(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{cell(v)}</td>" for v in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def html_chart(stem: str, alt: str, caption: str = "") -> str:
    """A chart of the report folder: ``stem.svg`` at full width (sharp at any zoom),
    a link to ``stem.png`` (the same chart as a picture), a caption under it."""
    note = escape(caption) + (" " if caption else "")
    return (
        f'<p><a href="{escape(stem)}.png"><img class="wide" src="{escape(stem)}.svg" '
        f'alt="{escape(alt)}"></a></p><p class="note">{note}'
        f'(<a href="{escape(stem)}.png">{escape(stem)}.png</a>: the same chart as a '
        "picture)</p>"
    )


def _figure(src: str, caption: str) -> str:
    return (
        f'<figure><a href="{escape(src)}"><img src="{escape(src)}" alt="overlay"></a>'
        f"<figcaption>{escape(caption)}</figcaption></figure>"
    )


def html_gallery(title: str, items: Sequence[tuple[str, str]], *, level: int = 2) -> str:
    """A heading with the count, then each ``(picture, caption)`` as a small figure
    linking to the picture ("None." when there are none)."""
    head = f"<h{level}>{escape(title)} ({len(items)})</h{level}>"
    if not items:
        return head + "<p>None.</p>"
    return head + "".join(_figure(src, caption) for src, caption in items)


def outcomes_html(counts: dict[str, int], coverage: float | None, answered: float | None) -> str:
    """The three outcomes (and the unreadable) as a small table, with the coverage and
    the accuracy of the answers given."""
    cov = "n/a" if coverage is None else f"{coverage:.0%}"
    acc = "n/a" if answered is None else f"{answered:.2%}"
    return html_table(
        ["right", "cannot tell", "wrong", "unreadable", "coverage (answered)",
         "right of the answers"],
        [[counts.get("right", 0), counts.get("cannot_tell", 0), counts.get("wrong", 0),
          counts.get("unreadable", 0), cov, acc]],
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


def evaluation_html(
    result: Any,
    meta: dict[str, Any],
    overlay_of: Callable[[Any], str],
    name: Callable,
    distances_note: str | None = None,
    risk_chart: bool = False,
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
    distances_note : str, optional
        What ``distances.svg`` shows (None: there is none).
    risk_chart : bool
        ``risk_coverage.svg`` is drawn (False: no answer had a confidence).
    """
    outs = result.outcomes
    wrong = [o for o in outs if o.predicted is not None and not o.correct]
    told = [o for o in outs if o.error is None and o.predicted is None]
    unread = [o for o in outs if o.error is not None]
    summary = [
        f"pairs: <b>{result.n}</b>",
        f"answers: {escape(result.outcomes_text())}",
        f"class accuracy over all pairs: {result.accuracy:.2%}; variant accuracy: "
        f"{escape(result.variant_accuracy_text())}",
        f"command: <code>{escape(str(meta.get('command', '')))}</code>",
        f"references: <code>{escape(str(meta.get('references', '')))}</code>, "
        f"dgli_vision {escape(str(meta.get('package_version', '')))}",
    ]
    return html_page(
        "dgli evaluate report",
        [
            html_list(summary, raw=True),
            outcomes_html(result.outcome_counts, result.coverage, result.accuracy_answered),
            "<h2>Confusion</h2>",
            html_chart("confusion", "confusion matrix",
                       "Rows: the true class; columns: the answer; none: answered "
                       "\"cannot tell\" or not read. Counts above, each row's shares below."),
            "<h2>Risk and coverage</h2>",
            "<p>Raising the confidence threshold answers fewer pairs, more of them right.</p>",
            html_chart("risk_coverage", "risk-coverage curve",
                       "Each point: the answers at or above one confidence threshold.")
            if risk_chart else "<p>No answer with a confidence to draw.</p>",
            html_gallery(
                "Wrong",
                [
                    (overlay_of(o), f"{o.pair.color}: true {name(o.pair.label)}, "
                     f"predicted {name(o.predicted)}")
                    for o in wrong
                ],
            ),
            html_gallery(
                "Cannot tell",
                [(overlay_of(o), f"{o.pair.color}: true {name(o.pair.label)}; {o.reason}")
                 for o in told],
            ),
            f"<h2>Not read ({len(unread)})</h2>",
            html_list([f"{o.pair.color}: {o.error or ''}" for o in unread]) if unread
            else "<p>None.</p>",
            *(
                ["<h2>Distances between the evaluated samples</h2>",
                 html_chart("distances", "distance matrix", distances_note)]
                if distances_note else []
            ),
        ],
    )
