"""Uranus from the JPL ephemeris DE405 and the rediscovery of Neptune (needs the ``[astro]`` extra)."""
