"""Coverage of sensor poses: which target points each covers, by three methods."""
