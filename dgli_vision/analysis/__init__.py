"""Many frames at once: evaluation, tracking, the paper's comparison, benchmarks.

Batch evaluation of labelled folders and its report (:mod:`.evaluate`,
:mod:`.evaluation_report`), the state timeline of a recording (:mod:`.track`), the
Davies-Bouldin comparison of dGLI against the baselines and the folding-sequence
analysis (:mod:`.compare`, :mod:`.baselines`), the robustness table
(:mod:`.robustness`), benchmarks (:mod:`.bench`, :mod:`.frame_bench`) and pictures
(:mod:`.report`).
"""
