"""The test suite is a package so that tests import shared helpers as ``tests.toy_*``."""
