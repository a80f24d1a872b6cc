"""Links: serial, socket, UDP, HTTP(S); the link state, outages, the stale watchdog, port owners."""
