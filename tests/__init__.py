"""monovo's tests, one folder per folder of the package (tests/core/plane/ tests monovo_cli/core/plane/).

Every folder is a package, so test files of the same name in two folders do not clash and
the helpers are imported by their full name (``from tests.helpers.plane_helpers import tilted``).
"""
