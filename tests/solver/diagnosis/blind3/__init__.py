"""Fifth blind campaign generator and scorer for hyperstat diagnose (issue 40, item 5)."""
