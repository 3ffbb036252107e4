"""Scoring matches: the figures of docs/evaluation.md (:mod:`.metrics`, also importable as ``cvstereo.evaluate``),
the thesis' published tables (:mod:`.thesis`) and the experiment tables the demo prints (:mod:`.experiment`).
"""

__all__: list[str] = []  # the names live in the modules; import them from there
