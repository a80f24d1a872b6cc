"""ros://: TCPROS and XML-RPC, ROS messages, RosLink and a Robot against a real ROS 1 master."""
