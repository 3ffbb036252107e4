"""The benchmark behind ``cvstereo bench`` (:mod:`.harness`) and its repeated CPU-time measurement
(:mod:`.timing`).
"""

__all__: list[str] = []  # the names live in the modules; import them from there
