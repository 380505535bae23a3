"""The simulated rig: a kinematic bimanual world that produces complete EgoTouch episodes.

World frame: metres, z up, the table top at z = 0, the person at y < 0 facing +y.
"""
