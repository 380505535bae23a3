"""Pure renderers (numpy / OpenCV, image out) shared by the dashboard and the video exporter: pressure panels,
colour maps, hand overlays, plots, contact lamps, comparison frames; and the dearpygui dashboard in
`viz/dashboard/`. Imports `devices` (never `devices.hardware`) and `inference`, never `app`."""
