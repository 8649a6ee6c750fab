"""What a person looks at: the live Foxglove view and ``ext-sense plot``'s figures.

The ``foxglove_view`` node (:mod:`.node`) and its part of every graph (:mod:`.graph`) only feed
messages in and send results out; everything drawn is plain NumPy (matplotlib for the
figures), tested without ROS, the same from a live graph or a bag.
"""
