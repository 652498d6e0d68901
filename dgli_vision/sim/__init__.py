"""The simulator and renderer that make the references and the test images.

Cloth states of the twelve classes and folding sequences (:mod:`.cloth`), the simulated
database (:mod:`.database`, :mod:`.database_files`), synthetic RGB-D renders
(:mod:`.render`, :mod:`.render_scene`, :mod:`.render_sheen`), the capture conditions
(:mod:`.condition_names`, :mod:`.conditions`, :mod:`.condition_effects`,
:mod:`.condition_scene`), rendered datasets and sequences (:mod:`.dataset`) and the
printable sticker sheet (:mod:`.sticker_sheet`).
"""
