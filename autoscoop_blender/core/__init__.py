"""Blender-free core of AutoSCOOP: numpy, scipy and shapely only.

Nothing in this package may import ``bpy``, ``mathutils`` or ``bmesh``; the Blender
glue in ``autoscoop_blender.scene`` converts scenes into the plain arrays used here.
"""
