"""Blind campaign generator and scorer for hyperstat's diagnosis (issue 28, item 7).

Written without reading hyperstat's diagnosis code; imports nothing from hyperstat.  See RULES.md.
No file here is named ``test_*``: pytest collects nothing from this package.
"""
