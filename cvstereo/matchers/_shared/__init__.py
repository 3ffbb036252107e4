"""Machinery several matchers share; private to :mod:`cvstereo.matchers`."""
