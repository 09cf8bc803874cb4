"""Corrade's Python module: habitat-lab imports it and uses nothing from it on the navigation paths."""
