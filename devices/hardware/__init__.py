"""The live device adapters behind one source contract (`threaded_source.ThreadedSource`): OpenCV/UVC and OAK
cameras, JQ pressure gloves, the Rokoko mocap receiver, OpenVR trackers; the registry from a scene's device
kind to its config and class, and discovery of what is attached. Imports only the `devices` root (never
`devices.episodes`)."""
