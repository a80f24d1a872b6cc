"""The galileo command: every subcommand, its options, JSON shapes, the monitor and the map."""
