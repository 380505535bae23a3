"""The simulated rig: a kinematic bimanual world that produces complete EgoTouch episodes, and the device
emulator that plays an episode through the real device protocols. Imports the `devices` root, `episodes`,
`hardware` and `rig`.

World frame: metres, z up, the table top at z = 0, the person at y < 0 facing +y.
"""
