"""Pure-numpy renderers and the dearpygui dashboard."""
