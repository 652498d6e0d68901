"""Everything that yields frames, or writes them.

RGB-D pairs and their decoding (:mod:`.frames`, :mod:`.pairing`), labelled folders
(:mod:`.labelled`), recordings: ROS 1 and ROS 2 bags and RealSense files
(:mod:`.recording` dispatches to :mod:`.ros_bags`, :mod:`.ros_images`,
:mod:`.realsense`, through the RealSense SDK), writing bags (:mod:`.bag_writer`,
:mod:`.realsense_writer`), extracting pairs from a
recording (:mod:`.extract`), and the files that describe a camera or a sticker kit
(:mod:`.intrinsics_files`, :mod:`.colours_file`).
"""
