"""SynTouch BioTac over the ext_sense serial/CAN bridge (docs/biotac_bridge.md); no rclpy."""
