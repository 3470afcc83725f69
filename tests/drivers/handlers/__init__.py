"""pyserial URL handlers for tests (registered through serial.protocol_handler_packages)."""
