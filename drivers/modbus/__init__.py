"""Instruments on Modbus: the cannon on a PLC (driver modbus-cannon; docs/instruments/modbus-cannon.md)."""
