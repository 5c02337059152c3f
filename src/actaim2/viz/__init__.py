"""What people look at: the live Foxglove view's messages (``foxglove_live``) and the offline
browser viewer of ``actaim2 view`` (``sources`` -> ``recording`` -> ``web_viewer``)."""
