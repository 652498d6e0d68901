"""dgli_vision."""
