"""Robots in the simulation: kinematics, the fleet's step (projection with weights, prescribed
motion), scans, controllers and the crowd's avoidance (see docs/robots.md)."""
