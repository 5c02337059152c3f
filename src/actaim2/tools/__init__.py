"""Checks of the repository itself, run as ``python -m actaim2.tools.<name>``."""
