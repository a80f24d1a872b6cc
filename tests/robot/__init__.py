"""The Robot: operations, stop, drive, turns, services, safety, exit paths, loop binding."""
