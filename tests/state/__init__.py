"""The status store and derived events: waiters, streams, placeholders of the serial node."""
