"""The report of a robustness run: what ``dgli robustness --report DIR`` writes, built in
memory (the CLI writes the files).

``robustness.json`` (the object of ``--json``), ``report.md`` and ``report.html``: the
robustness table (right, "cannot tell", wrong per condition, with the coverage and the
accuracy of the answers), the three outcomes over all conditions, the reliability table,
and per condition a gallery of the pairs answered wrong or "cannot tell" with their
overlays (``overlays/<condition>/<name>.png``) and reasons.
"""

from __future__ import annotations

from html import escape
from typing import Any

from ..core.words import counted
from .charts import chart_files, outcomes_figure
from .evaluate import outcome_fields, outcomes_text
from .html_report import (
    cannot_tell_text,
    html_chart,
    html_gallery,
    html_list,
    html_page,
    html_table,
    outcomes_html,
)
from .report import markdown_table
from .robustness import (
    ConditionScore,
    ShownPair,
    reliability_rows,
    reliability_table,
    robustness_table,
)

__all__ = [
    "GALLERY_MAX",
    "ROBUSTNESS_REPORT_FILES",
    "robustness_json",
    "robustness_report",
    "total_outcomes",
]

#: The files of every robustness report (besides the overlays).
ROBUSTNESS_REPORT_FILES = ("robustness.json", "report.md", "report.html", "outcomes.svg",
                           "outcomes.png")

#: Most pairs of each kind (wrong, "cannot tell") a condition's gallery shows; the rest
#: are counted, not drawn.
GALLERY_MAX = 12


def total_outcomes(scores: list[ConditionScore]) -> dict[str, Any]:
    """``"outcomes"``, ``"coverage"`` and ``"accuracy_answered"`` over all conditions (rows
    that are parts of another condition's pairs are not counted twice)."""
    total = {"right": 0, "cannot_tell": 0, "wrong": 0, "unreadable": 0}
    for s in scores:
        if not s.subset:
            for k, v in s.outcome_counts.items():
                total[k] += v
    return outcome_fields(total)


def _file(condition: str, pair: ShownPair) -> str:
    return f"overlays/{condition.replace(' ', '_')}/{pair.name}.png"


def _caption(pair: ShownPair) -> str:
    drawn = "+".join(pair.drawn) or "clean"
    if pair.answer is None:
        return f"{pair.name} ({drawn}): true {pair.truth}; {cannot_tell_text(pair.reason)}"
    return f"{pair.name} ({drawn}): true {pair.truth}, answered {pair.answer}"


def _kept(score: ConditionScore) -> dict[str, list[ShownPair]]:
    """The pairs each gallery of a condition shows (at most :data:`GALLERY_MAX` a kind)."""
    return {
        kind: [p for p in score.shown if p.kind == kind][:GALLERY_MAX]
        for kind in ("wrong", "cannot tell")
    }


def _counts_line(score: ConditionScore, kept: dict[str, list]) -> str:
    n = {"wrong": score.wrong, "cannot tell": score.abstained}
    more = [f"{n[k] - len(v)} more {k} not drawn" for k, v in kept.items() if n[k] > len(v)]
    text = f"right {score.right} of {score.n}; wrong {score.wrong}; cannot tell {score.abstained}"
    return text + (f" ({', '.join(more)})" if more else "")


def _markdown(title: str, lines: list[str], scores: list[ConditionScore]) -> str:
    md = [f"# {title}", "", *[f"- {line}" for line in lines], "", "## By condition", "",
          markdown_table(*robustness_table(scores)), "", "![answers](outcomes.png)", "",
          "## Reliability (best guesses over all conditions)", "",
          markdown_table(*reliability_table(scores)), ""]
    for s in scores:
        if s.subset:
            continue
        kept = _kept(s)
        md += [f"## {s.condition}", "", _counts_line(s, kept), ""]
        for kind, pairs in kept.items():
            md += [f"### {kind.capitalize()}", ""]
            md += [f"- [{_caption(p)}]({_file(s.condition, p)})" for p in pairs] or ["None."]
            md += [""]
    return "\n".join(md) + "\n"


def _html(title: str, lines: list[str], totals: dict, scores: list[ConditionScore]) -> str:
    body = [
        html_list(lines),
        outcomes_html(totals["outcomes"], totals["coverage"], totals["accuracy_answered"]),
        "<h2>By condition</h2>",
        html_chart("outcomes", "answers under each condition",
                   "Each bar: the pairs rendered under that condition."),
        html_table(*robustness_table(scores)),
        "<h2>Reliability (best guesses over all conditions)</h2>",
        "<p>How often the best guess is right at each confidence, those below the "
        "threshold that became \"cannot tell\" included.</p>",
        html_table(*reliability_table(scores)),
    ]
    for s in scores:
        if s.subset:
            continue
        kept = _kept(s)
        body += [f"<h2>{escape(s.condition)}</h2>", f"<p>{escape(_counts_line(s, kept))}</p>"]
        for kind, pairs in kept.items():
            body.append(html_gallery(kind.capitalize(),
                                     [(_file(s.condition, p), _caption(p)) for p in pairs],
                                     level=3))
    return html_page(title, body)


def robustness_report(
    scores: list[ConditionScore], data: dict[str, Any], *, command: str
) -> dict[str, Any]:
    """All files of a robustness report: name -> JSON-ready dict, Markdown/HTML text or
    BGR image.

    Parameters
    ----------
    scores : list of ConditionScore
        With the pairs to show (``score_condition(..., overlays=True)``).
    data : dict
        The JSON object of ``dgli robustness --json``.
    command : str
        The command line, for the record.
    """
    totals = total_outcomes(scores)
    title = "dgli robustness report"
    lines = [
        f"pairs: {sum(s.n for s in scores if not s.subset)} over "
        f"{counted(sum(not s.subset for s in scores), 'condition')} (seed {data.get('seed')}, "
        f"{data.get('per_class')} per class)",
        "answers: " + outcomes_text(totals["outcomes"]),
        f"command: {command}",
    ]
    files: dict[str, Any] = {"robustness.json": {"command": command, **data}}
    for s in scores:
        if s.subset:
            continue
        for pairs in _kept(s).values():
            for p in pairs:
                if p.overlay is not None:
                    files[_file(s.condition, p)] = p.overlay
    files.update(chart_files("outcomes", outcomes_figure(
        [(s.condition, s.right, s.abstained, s.wrong) for s in scores]
    )))
    files["report.md"] = _markdown(title, lines, scores)
    files["report.html"] = _html(title, lines, totals, scores)
    return files


def robustness_json(seed: int, per_class: int, scores: list[ConditionScore]) -> dict[str, Any]:
    """The JSON of ``dgli robustness --json`` (and ``robustness.json``; docs/json.md):
    the outcomes over all conditions, a row per condition, the wrong answers and the
    reliability table."""
    return {
        "seed": seed,
        "per_class": per_class,
        **total_outcomes(scores),
        "rows": [s.to_json() for s in scores],
        "wrong": {s.condition: list(s.wrong_cases) for s in scores},
        "reliability": reliability_rows(scores),
    }
