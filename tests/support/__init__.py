"""Support of the tests: fake robots, real peers, test vectors and harnesses (no tests)."""
