"""The plain data a run starts from: the scene and the sensor models."""
