"""Blender glue: scene extraction, the BVHTree ray caster, results in the scene."""
