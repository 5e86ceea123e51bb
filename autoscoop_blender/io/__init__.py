"""Files in and out, Blender-free: config, sensors files, reports, the coverage map."""
