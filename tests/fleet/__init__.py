"""Fleets: connect_fleet, fleet files, merged streams, stopping every robot."""
