"""The kilonova source model: light curves, the night's depth, and the expected detections of a plan."""
