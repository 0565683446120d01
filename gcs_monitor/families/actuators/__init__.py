"""Actuator family: control-surface servo faults (Lu2017 servo level, where surface or rod
position feedback is reported) and surface/engine faults from standard MAVLink (issue 17)."""
