"""The simulator: its robot model, its device faces (serial, TCP, pty, HTTP) and memory pair."""
