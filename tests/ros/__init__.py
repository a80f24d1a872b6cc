"""ros://: TCPROS and XML-RPC, ROS messages, RosChannel and a Robot against a real ROS 1 master."""
