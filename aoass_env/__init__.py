"""AOASS: a single mobile anchor sweeping a sensor field along a square spiral."""
