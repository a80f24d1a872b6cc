"""The testing kit (galileo_async.testing): virtual clock, simulated robots, the pytest plugin."""
