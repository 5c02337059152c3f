"""What people look at: the live Foxglove view's messages (``foxglove_live``)."""
