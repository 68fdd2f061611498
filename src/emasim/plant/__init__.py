"""Continuous-time physics of the actuator, SI units, one module per physical thing."""
