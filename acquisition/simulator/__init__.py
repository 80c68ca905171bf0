"""A simulated vehicle that speaks MAVLink like ArduPilot or PX4 (it says it is a simulator)."""
