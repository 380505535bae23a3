"""The dearpygui dashboard: cameras with hand overlays, pressure maps, contact lamps, metrics, timings, device
status and controls, driven by any session that implements `DashboardSession` (`dashboard_state`). Imports
`devices`, `inference` and the `viz` renderers; never `app` (sessions depend on the dashboard, not back)."""
