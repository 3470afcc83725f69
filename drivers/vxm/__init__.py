"""A Velmex VXM-class stepper stage for the impact point plus a USB swing sensor (driver `vxm-stage`)."""
