"""Blender-free core of AutoSCOOP: numpy, scipy and shapely only.

The pipeline, one stage per module or folder, each handing its output to the next:
``model`` (the scene and the sensors as plain data) -> ``geom`` (ray casting, the
ground grid) -> ``coverage`` (what a pose covers) -> ``problem`` (built once) ->
``candidates`` -> ``optimize`` (the strategies) -> ``masts`` -> ``result`` (world
metres, draped footprints, metrics; no caster). ``run.py`` drives an optimization
through it and ``evaluate.py`` a given layout; ``settings.py`` defines every knob.

Nothing in this package may import ``bpy``, ``mathutils`` or ``bmesh``; the Blender
glue in ``autoscoop_blender.scene`` converts scenes into the plain arrays used here.
"""
