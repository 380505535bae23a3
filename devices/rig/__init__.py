"""What combines sources into one rig: the rig inputs and the 30 Hz rig clock (Snapshots), the mocap →
head-camera pose transform, live tactile grids, the episode recorder, and replay of recorded episodes. Imports
the `devices` root, `devices.episodes` and `devices.hardware`."""
