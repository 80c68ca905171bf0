"""acquisition: MAVLink links, mission transfer, the simulated vehicle, telemetry and geotagging."""
