"""The bottom floor: the maths and the conventions every other folder shares.

The GLI and dGLI cloth coordinates (:mod:`.dgli`), distances between coordinate vectors
(:mod:`.distance`), the camera and its lens (:mod:`.camera`), the napkin's layout and
sticker geometry (:mod:`.layout`, numbers in ``data/napkin.json``), the twelve classes and
their fold graph (:mod:`.classes`, :mod:`.fold_graph`), colour conversions
(:mod:`.colour`), the errors (:mod:`.errors`) and file writing that never loses work
(:mod:`.io`, :mod:`.run_lock`). Nothing here imports from another folder.
"""
