"""The data model: events and their dtype (:mod:`.events`), recordings (:mod:`.recording`), matches
(:mod:`.matches`), polarity handling (:mod:`.polarity`), the array API users' shapes come in through
(:mod:`.arrays`), the value checks of raw columns (:mod:`.columns`), sensor sizes (:mod:`.sensor_size`) and the
fingerprint of a recording's events (:mod:`.fingerprint`). Everything else builds on these.
"""

__all__: list[str] = []  # the names live in the modules; import them from there
