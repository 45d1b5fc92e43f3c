"""Vision: image basics in numpy/scipy (Gaussian, Sobel, Canny, Harris/Shi-Tomasi, pyramids,
undistortion by remapping: :mod:`~slamkit.vision.image`), pyramidal Lucas-Kanade tracking
(:mod:`~slamkit.vision.klt`), ORB features and Hamming matching (:mod:`~slamkit.vision.orb`,
the only cv2 importer), two-view geometry, triangulation and PnP
(:mod:`~slamkit.vision.two_view`, :mod:`~slamkit.vision.pnp`).

Layer: imports geometry and models only (tests/test_layers.py)."""
