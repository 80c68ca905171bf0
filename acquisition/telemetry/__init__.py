"""Readers of flight logs into the normalized tables of :mod:`acquisition.telemetry.model`."""
