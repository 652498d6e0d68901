"""What a frame means: references, distances, the verdict and its checks.

:mod:`.references` (the simulated class representatives and what each keeps),
:mod:`.classify` (the distance to every reference and the verdict with its confidence),
:mod:`.consistency` (a wrong depth scale, an uncorrected lens, a mirrored napkin, a
footprint the state cannot have: "cannot tell"), :mod:`.pipeline` (one frame through
perception and the classifier) and :mod:`.api` (:func:`dgli_vision.classify_pair`).
"""
