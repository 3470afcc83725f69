"""The population study (founding paper, section 5) and the simulated populations it is tried on."""
