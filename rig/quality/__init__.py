"""Quality control of the lab's results (ISO/IEC 17025 7.7.1): check standards on control charts."""
