"""``dgli compare``'s table as people read it: the paper's value right after ours that
compares with it (the merged grouping for its database, III for its III), those first."""

from __future__ import annotations

from dgli_vision.analysis.compare_report import paper_beside_ours


def test_the_papers_columns_stand_beside_the_comparable_ones():
    columns = ["representation", "database", "I", "II", "III", "database by variant",
               "by variant, mirrors merged", "paper: database", "paper: III"]
    row = ["dgli", "46.7", "1", "2", "0.3", "2.19", "0.57", "0.73", "0.21"]
    cols, (out,) = paper_beside_ours(columns, [row])
    assert cols == ["representation", "by variant, mirrors merged", "paper: database", "III",
                    "paper: III", "database", "I", "II", "database by variant"]
    assert out == ["dgli", "0.57", "0.73", "0.3", "0.21", "46.7", "1", "2", "2.19"]
