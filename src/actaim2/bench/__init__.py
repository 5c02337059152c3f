"""Benchmarks behind `actaim2 bench <area>`: each module prints a markdown table."""
