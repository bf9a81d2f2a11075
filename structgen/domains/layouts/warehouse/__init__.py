"""Robots on warehouse and manufacturing floors: the simulator and its compiled planners."""
