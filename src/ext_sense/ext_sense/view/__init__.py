"""What a person looks at: the live Foxglove view's pictures and ``ext-sense plot``'s figures.

Plain NumPy (and matplotlib for the figures), no rclpy: the view node
(:mod:`ext_sense.nodes.foxglove_view`) only feeds messages in and sends the results out, so
everything drawn here is tested without ROS and draws the same from a live graph or a bag.

- :mod:`.images`: RGB images as arrays, the colour map, rectangles.
- :mod:`.taxels`: the taxel grid (NUSkin rate, BioTac electrodes) with dead and saturated marks.
- :mod:`.traces`: event rate per finger, the BioTac PAC trace.
- :mod:`.raster`: a contact window as a taxels x time raster with its onset.
- :mod:`.estimate`: an estimate drawn (tap on the rod, class bars, stability) and summed up.
- :mod:`.feed`: the sensor input: the drivers' raw packets decoded, or decoded arrays.
- :mod:`.pacing`: the display-rate gate.
- :mod:`.channels`: the view's channel names and JSON schemas.
- :mod:`.layout`: the Foxglove layout shipped with the package.
- :mod:`.sessions`, :mod:`.figures`: ``ext-sense plot`` (bags and capture folders to PNGs).
"""
