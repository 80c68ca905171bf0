"""planner: from an area, a camera and a target GSD to a flyable MAVLink survey.

Imports nothing else of sfap. See DESIGN.md for the module map.
"""
