"""What a person looks at: the live Foxglove view and ``ext-sense plot``'s figures.

The view's node (:mod:`.node`) and its part of every graph (:mod:`.graph`) live here beside
its pictures; the node only feeds messages in and sends the results out. Everything else is
plain NumPy (and matplotlib for the figures), no rclpy, so everything drawn is tested without
ROS and draws the same from a live graph or a bag.

- :mod:`.node`: the ``foxglove_view`` node (a Foxglove WebSocket server).
- :mod:`.graph`: the ``view`` arguments and the node that ``view:=true`` adds to a graph.

- :mod:`.images`: RGB images as arrays, the colour map, rectangles.
- :mod:`.taxels`: the taxel grid (NUSkin rate, BioTac electrodes) with dead and saturated marks.
- :mod:`.traces`: event rate per finger, the BioTac PAC trace.
- :mod:`.raster`: a contact window as a taxels x time raster with its onset.
- :mod:`.estimate`: an estimate drawn (tap on the rod, class bars, stability) and summed up.
- :mod:`.feed`: the sensor input: the drivers' raw packets, decoded here.
- :mod:`.pacing`: the display-rate gate.
- :mod:`.channels`: the view's channel names and JSON schemas.
- :mod:`.layout`: the Foxglove layout shipped with the package.
- :mod:`.sessions`, :mod:`.figures`: ``ext-sense plot`` (bags and capture folders to PNGs).
"""
