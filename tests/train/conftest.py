"""One torch thread for the training tests (tests/torch_threads.py says why)."""
from torch_threads import one_torch_thread  # noqa: F401  (autouse for this folder)
