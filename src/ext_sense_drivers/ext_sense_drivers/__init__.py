"""Device drivers: NUSkin receiver words and ACES line, BioTac serial bridge; transports (serial, CAN, file)."""
