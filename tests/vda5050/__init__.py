"""The VDA 5050 vehicle: conformance, schemas, links, secrets, shutdown, against Mosquitto."""
