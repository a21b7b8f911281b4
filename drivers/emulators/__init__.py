"""Device emulators: a streaming serial DAQ and a capture-buffer Modbus DAQ (tests, demo, CLI)."""
