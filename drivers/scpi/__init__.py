"""SCPI instruments over VISA: a sans-I/O codec per instrument class, one VISA line transport."""
