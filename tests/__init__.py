"""The tests, in folders by part; support/ holds their fakes, peers and harnesses."""
