"""The dataset registry's data: every file, its checksum and source, and one entry per dataset.

Generated once from ``../shared/datasets/MANIFEST.md`` (file index, licences, counts, published
and "gtsam local check" reference values) and from the gtsam 4.3.0 wheel's ``Data`` folder
(sha256 computed from the wheel's copies), then edited by hand. A Python table rather than
YAML/JSON so that ``slamkit.data`` needs no YAML import and the table ships inside the package.
Read through :mod:`slamkit.data.registry`; never import this module for anything else.
"""

from __future__ import annotations

# ruff: noqa: E501

#: every file of ../shared/datasets (MANIFEST.md file index): relative path ->
#: (bytes, sha256, source repository, path in it, commit, git blob)
SHARED_FILES: dict[str, tuple[int, str, str, str, str, str]] = {
    "pose_graph_2d/intel.g2o": (307_525, "3e0724c048e0ba524be9dd268a8b78e19a2497043143584cbb61310638b15c4b",
        "david-m-rosen/SE-Sync", "data/intel.g2o", "9b631b6b82d8", "6120178b19f6"),
    "pose_graph_2d/input_INTEL_g2o.g2o": (216_371, "e648e42b1f24ab01cce76f56c8d8dad0b606f712afe2b92356bf26f195c602be",
        "mit-acl/dpgo", "data/input_INTEL_g2o.g2o", "a238090c6427", "16f3a2600cb5"),
    "pose_graph_2d/intel_g2o_943.g2o": (155_587, "4d87aaf96e1e04e47c723c371386b15358c71e98c05dad16b786d585f9fd70ff",
        "OpenSLAM-org/openslam_g2o", "data/2d/intel/intel.g2o", "967599368197", "6a5a55495c49"),
    "pose_graph_2d/input_MITb_g2o.g2o": (121_424, "e5922be0d0689c7a5bc04c58adf3a8e697e240bdd7691cc4218470eaf92956eb",
        "mit-acl/dpgo", "data/input_MITb_g2o.g2o", "a238090c6427", "2c329e337331"),
    "pose_graph_2d/CSAIL.g2o": (127_618, "66d99ac857a9849d814d214a9ebd0d4876d5d40f0a37be9330c1ff6e6e9daaa6",
        "david-m-rosen/SE-Sync", "data/CSAIL.g2o", "9b631b6b82d8", "986c39e0808a"),
    "pose_graph_2d/CSAIL_P_toro.graph": (166_663, "fcf4de76b262e7f58ea64b8c5db806fec926a519d2f5d85fcc9c553f8f82fa98",
        "gisbi-kim/nano-pgo", "data/CSAIL_P_toro.graph", "b85562f0acda", "0ee14b70faf3"),
    "pose_graph_2d/FR079_P_toro.graph": (168_737, "ba53624ae4ed843258359c8e5713e7456943b6daf2e4a17b800a90e170d7e659",
        "gisbi-kim/nano-pgo", "data/FR079_P_toro.graph", "b85562f0acda", "7176f18a28db"),
    "pose_graph_2d/FRH_P_toro.graph": (345_919, "56868ab910e876e358ab74478c55f48aa6275bd133739f927510e442b3a523ee",
        "gisbi-kim/nano-pgo", "data/FRH_P_toro.graph", "b85562f0acda", "1937e066a1e5"),
    "pose_graph_2d/manhattan.g2o": (594_668, "6ae8d30971720c1af24a00c4b2dd5c5ddafbbbe488bfc771145c47decbffb248",
        "david-m-rosen/SE-Sync", "data/manhattan.g2o", "9b631b6b82d8", "d69f29d8a3c6"),
    "pose_graph_2d/input_M3500_g2o.g2o": (727_872, "1883593980e602b11bd0ba95799c969e59ee8a6892bdb2a3a48f495459efe9d8",
        "mit-acl/dpgo", "data/input_M3500_g2o.g2o", "a238090c6427", "e3a7a678c933"),
    "pose_graph_2d/input_M3500b_g2o.g2o": (724_326, "55342238a0d45d724ce590202f4c3ad3004e02c3d770e029677030b50a632f48",
        "gisbi-kim/nano-pgo", "data/input_M3500b_g2o.g2o", "b85562f0acda", "2ba2cfed931f"),
    "pose_graph_2d/manhattanOlson3500.g2o": (648_160, "84d6ac6faffe2f120bd8df6f80185db0fafacdd9c0eedfa118ae475e035f9f40",
        "OpenSLAM-org/openslam_g2o", "data/2d/manhattan3500/manhattanOlson3500.g2o", "967599368197", "61ac2bb3c1bb"),
    "pose_graph_2d/manhattanOlson3500_groundtruth_nodes.dat": (89_448, "8512b270849f2571ace2f5fac486d3ee9b686e8334c7c55a6f96c2025a413181",
        "OpenSLAM-org/openslam_vertigo", "datasets/manhattan/groundTruth/manhattanOlson3500_nodes_groundTruth.dat", "e57e88cbc175", "5796ea87f9b2"),
    "pose_graph_2d/city10000.g2o": (1_750_622, "df5988994339e990be198a36e7f640e31a5a1b26df3ed400363fafc49d5ca630",
        "david-m-rosen/SE-Sync", "data/city10000.g2o", "9b631b6b82d8", "cd8bc910725b"),
    "pose_graph_2d/ais2klinik.g2o": (2_236_921, "e388ebd8523987c1004082d7eaeb5e6fb640b773d05ccebeef1ce1e8df64e1e7",
        "david-m-rosen/SE-Sync", "data/ais2klinik.g2o", "9b631b6b82d8", "a54c0ceb4645"),
    "pose_graph_2d/ring.g2o": (57_528, "786a004adc98e7a530d3ba3c11200f7d8ba6cad6ca59929d64e1cbbf164d49aa",
        "OpenSLAM-org/openslam_vertigo", "datasets/ring/originalDataset/ring.g2o", "e57e88cbc175", "b0fae11eeef3"),
    "pose_graph_2d/ring_groundtruth_poses.txt": (14_453, "89294c68515cf833362d5f94f35a38879745f7d0a9fd22c86ce880b864fa3fe0",
        "OpenSLAM-org/openslam_vertigo", "datasets/ring/groundTruth/poses.txt", "e57e88cbc175", "41f142b160e4"),
    "pose_graph_2d/ringCity.g2o": (382_619, "059b6def507e46b86c236b18cae00f3308063258c378feca42540b703a218ebd",
        "OpenSLAM-org/openslam_vertigo", "datasets/ringCity/originalDataset/ringCity.g2o", "e57e88cbc175", "90b4afbed135"),
    "pose_graph_2d/ringCity_groundtruth_poses.txt": (80_303, "abacfe18e728280bcd287c0416b88725778c930787beef122d42f4425186b351",
        "OpenSLAM-org/openslam_vertigo", "datasets/ringCity/groundTruth/poses.txt", "e57e88cbc175", "1e015fa15dfd"),
    "pose_graph_2d_kitti/kitti_00.g2o": (545_590, "8a9807f604852a44254910100917918def94d7357748c633e1fd7ce73dd17468",
        "david-m-rosen/SE-Sync", "data/kitti_00.g2o", "9b631b6b82d8", "e4863573ca2b"),
    "pose_graph_2d_kitti/kitti_02.g2o": (558_300, "2a77a2c27e2e3afcde6f189c132ca6a228afd1a73d8509cfbcac2201555dd3e7",
        "david-m-rosen/SE-Sync", "data/kitti_02.g2o", "9b631b6b82d8", "fdb361f85024"),
    "pose_graph_2d_kitti/kitti_05.g2o": (334_593, "05a85336eaaae8f7d22226d38a1829f305ac49ad1a71c488bcd71672ca0ff9e3",
        "david-m-rosen/SE-Sync", "data/kitti_05.g2o", "9b631b6b82d8", "636ca29f0cc5"),
    "pose_graph_2d_kitti/kitti_06.g2o": (138_334, "0a6513dfdb62932099c786c27e3dc0fdc0e2c893ed6dbe6ad628e4e4f2457cf8",
        "mit-acl/dpgo", "data/kitti_06.g2o", "a238090c6427", "403ad22b68b0"),
    "pose_graph_2d_kitti/kitti_07.g2o": (130_672, "644a67327bb02a6a34f8b5ed079a0062554522a5fcabcac184565dc2722edf2c",
        "mit-acl/dpgo", "data/kitti_07.g2o", "a238090c6427", "da681b28e06b"),
    "pose_graph_2d_kitti/kitti_08.g2o": (487_120, "020f93d61dcc89f6d1a022afc25de19462692012c27a21ae189e3056247f30f1",
        "mit-acl/dpgo", "data/kitti_08.g2o", "a238090c6427", "82c5dd21bfb3"),
    "pose_graph_2d_kitti/kitti_09.g2o": (189_039, "c0f33bd2cd48979463edbe06853400c28106821c626c8711dc9a95f96b55515b",
        "mit-acl/dpgo", "data/kitti_09.g2o", "a238090c6427", "6e367d8f82c4"),
    "pose_graph_3d/sphere2500.g2o": (1_094_712, "104ab57593394f24351d9f692f3b923f8b98fff1eb638c64356cf5049e06cf3c",
        "david-m-rosen/SE-Sync", "data/sphere2500.g2o", "9b631b6b82d8", "1c9c3a5fb0c4"),
    "pose_graph_3d/torus3D.g2o": (3_262_828, "1ef8831023b372188d33ca63ce0da079d51df89364df71f2bce1c5c7c69ed5ec",
        "david-m-rosen/SE-Sync", "data/torus3D.g2o", "9b631b6b82d8", "1e142a219f5d"),
    "pose_graph_3d/parking-garage.g2o": (1_281_113, "3ac0a31bfb601d7455d451e2546655cb5dececf51a7823f57c8a7e0fe1ca6527",
        "david-m-rosen/SE-Sync", "data/parking-garage.g2o", "9b631b6b82d8", "2d1ad6aefdb7"),
    "pose_graph_3d/cubicle.g2o": (2_687_081, "f7781d485383cec86d47d7650970132c36d6f3a1f4e5d62a49b7f8245c0a6465",
        "david-m-rosen/SE-Sync", "data/cubicle.g2o", "9b631b6b82d8", "5b1fba871239"),
    "pose_graph_3d/sphere_bignoise_vertex3.g2o": (2_221_712, "484aa1999084d353d83725ba1d992cb709ad3a7e6c396155cc8e87a059c645db",
        "david-m-rosen/SE-Sync", "data/sphere_bignoise_vertex3.g2o", "9b631b6b82d8", "c09e6f4c0f97"),
    "pose_graph_3d/smallGrid3D.g2o": (101_258, "9ea56c2ad1ebcc322560eb2f8d83cb3a60f99e2e2acc35e097b1162cdbafd649",
        "david-m-rosen/SE-Sync", "data/smallGrid3D.g2o", "9b631b6b82d8", "2f3fb56d9fe4"),
    "pose_graph_3d/tinyGrid3D.g2o": (4_106, "c341eb0d09f7556b337be5a62b9354384885333a25fa718fd699fafb19620493",
        "david-m-rosen/SE-Sync", "data/tinyGrid3D.g2o", "9b631b6b82d8", "52a0b1ea736e"),
    "pose_graph_3d/sphere400.txt": (94_417, "53d79ca95109c43f895f0bf100a144cbf45b9695d214233b3387512997b0694e",
        "rickytan/iSAM", "data/sphere400.txt", "617b3ff15441", "7ff0e0aaa1db"),
    "landmark_2d/cityTrees10000.txt": (804_842, "62760029d3b492f357117a3922b57a68585b137fbcb7a115def597ab7a4f2c24",
        "rickytan/iSAM", "data/cityTrees10000.txt", "617b3ff15441", "3e16593a3a67"),
    "landmark_2d/cityTrees10000_groundtruth.txt": (540_154, "0ff138c64003d0fcf7a8d864a99de4d98d57f7b487096fa81abd7f53a8b63c04",
        "rickytan/iSAM", "data/groundtruth/cityTrees10000_groundtruth.txt", "617b3ff15441", "bd720f6e347c"),
    "landmark_2d/MRCLAM_Dataset1/Barcodes.dat": (404, "11049b54d75d8142297fe6473686dc406e0d74312b1dc679c6f3c3d826328a0b",
        "curow/multi-robot-localization", "MRCLAM/MRCLAM_Dataset1/Barcodes.dat", "adf911135415", "3b4c2f710b2d"),
    "landmark_2d/MRCLAM_Dataset1/Landmark_Groundtruth.dat": (1_098, "682c416aafb066992e964ef4233ee9054f41f0e18501409bf5efd005fef152d8",
        "curow/multi-robot-localization", "MRCLAM/MRCLAM_Dataset1/Landmark_Groundtruth.dat", "adf911135415", "6e3a0d93f391"),
    "landmark_2d/MRCLAM_Dataset1/Robot1_Odometry.dat": (3_328_485, "51a3f6362684a3993c50fcde83fd89eac49f68acd1568cb2f399680b88afab81",
        "curow/multi-robot-localization", "MRCLAM/MRCLAM_Dataset1/Robot1_Odometry.dat", "adf911135415", "b81761b0665c"),
    "landmark_2d/MRCLAM_Dataset1/Robot1_Measurement.dat": (229_138, "3257dd730fe65773e0a093c2aa45da998ab8c790f666d0477f6976d03aef1abf",
        "curow/multi-robot-localization", "MRCLAM/MRCLAM_Dataset1/Robot1_Measurement.dat", "adf911135415", "8d26fbe13e8b"),
    "landmark_2d/mrclam5a.pyfg": (372_032, "877356d60d781fe737f4058822861bb2831c806f7d1f0f91e3288eb3fdc4fcd0",
        "MarineRoboticsGroup/cora", "examples/data/mrclam/range_and_rpm/mrclam5a/mrclam5a.pyfg", "015dc43340ca", "c1955d0cd68c"),
    "landmark_3d/torus2000Points.txt": (313_866, "8b370f366697917aa4720dc07087cdea50f265e4baea4c162de0820d86b92631",
        "rickytan/iSAM", "data/torus2000Points.txt", "617b3ff15441", "a9e77a1774f0"),
    "grid_planning/movingai/dao/arena.map": (2_485, "9887c3022fb76d8e2b49db4a54641e31df79607cf96c2a0ec362702808113d4d",
        "nathansttt/hog2", "maps/dao/arena.map", "70842df4bb97", "24f348f18d13"),
    "grid_planning/movingai/dao/arena.map.scen": (7_269, "b631475cd551e2e5bb6d4585131197c13be27fcea18a19deb03c1ebf9fce2fc8",
        "nathansttt/hog2", "trunk/scenarios/dao/arena.map.scen", "c3a772f2db93", "cb368547c01c"),
    "grid_planning/movingai/dao/den312d.map": (5_381, "1b3d72a358329a9a37d0aed62ad2668ee7882c4c745c73dc8b4f5d75493c79c4",
        "nathansttt/hog2", "maps/dao/den312d.map", "70842df4bb97", "e4f157d2900b"),
    "grid_planning/movingai/dao/den312d.map.scen": (15_732, "1018ffb43c265b2faa946eb7cff41c6541d82ae3cfddf38f1e6326c01e42a188",
        "nathansttt/hog2", "trunk/scenarios/dao/den312d.map.scen", "c3a772f2db93", "df4f4b3a8b1e"),
    "grid_planning/movingai/dao/den520d.map": (66_086, "06575cc259ea90e6dad003a72f891ab9f82cc9f5e5de4a5f46b90125a46e5f90",
        "nathansttt/hog2", "maps/dao/den520d.map", "70842df4bb97", "b272cd45bccc"),
    "grid_planning/movingai/dao/den520d.map.scen": (48_225, "51262ff126c19f478f716c999e6098c850f4e6882e722de01a66931f15c04b2d",
        "nathansttt/hog2", "trunk/scenarios/dao/den520d.map.scen", "c3a772f2db93", "bb246d866b56"),
    "grid_planning/movingai/dao/brc202d.map": (255_448, "ee4f1b89431452b6a07f7a56c6ca653edd7f9f9f32906ab8280fb1a76e4b8a24",
        "nathansttt/hog2", "maps/dao/brc202d.map", "70842df4bb97", "2cd2ea9ad30d"),
    "grid_planning/movingai/dao/brc202d.map.scen": (140_977, "6452fc8facd55ceafed7ae5ce2f89a760a4972c635e9933cdc52ea9f3f70eea5",
        "nathansttt/hog2", "trunk/scenarios/dao/brc202d.map.scen", "c3a772f2db93", "e4534d9ccb96"),
    "grid_planning/movingai/street/Berlin_0_256.map": (66_087, "9fc2a576f930a7df9646969bed1e1a48d1f2e0c30574d2f72586901bc00ba1d4",
        "nathansttt/hog2", "maps/cities/Berlin_0_256.map", "70842df4bb97", "8e85f28818ab"),
    "grid_planning/movingai/street/Berlin_0_256.map.scen": (50_837, "b8079ed2260df9c9d40748444f6accbea5f5eeaa6bd046880203046616c85d62",
        "nathansttt/hog2", "maps/cities/map/Berlin_0_256.map.scen", "ac452c1c954d", "b0dce64f520e"),
    "grid_planning/movingai/street/Boston_0_256.map": (66_089, "992299786882228ff5e27112e7422124912bffec42655bb5d2375f4fd9ba8102",
        "nathansttt/hog2", "maps/cities/Boston_0_256.map", "70842df4bb97", "07ba61412ef1"),
    "grid_planning/movingai/street/Boston_0_256.map.scen": (51_942, "8010f0208ae82616c4158b58fbdbe7e6aa48a6caff0556a9df7f94114d0a6e38",
        "nathansttt/hog2", "maps/cities/map/Boston_0_256.map.scen", "ac452c1c954d", "edd81d50069f"),
    "grid_planning/movingai/room/8room_000.map": (262_693, "a4bb11d357f47295a07f2f57cd40fca4853fbe87dd476b9a53e3430739e07b99",
        "nathansttt/hog2", "maps/rooms/8room_000.map", "70842df4bb97", "d39ba414b9c6"),
    "grid_planning/movingai/room/8room_000.map.scen": (114_942, "08940a4aa01cc51214f89029ee4c5fca5e6d625c8e8df64e4a449856b32d4e29",
        "nathansttt/hog2", "trunk/scenarios/rooms/8room_000.map.scen", "c3a772f2db93", "a58ea96cbf63"),
    "grid_planning/movingai/room/32room_000.map": (262_693, "57fe06dadf5caa09c45e823521fc548398a1ebcc1c7dd89ffcee049146b88db9",
        "nathansttt/hog2", "maps/rooms/32room_000.map", "70842df4bb97", "909d63625620"),
    "grid_planning/movingai/room/32room_000.map.scen": (114_480, "adad9d786325ab627944863263a90054aa9b6f3ca1d6bae8f2902eca5015e2ff",
        "nathansttt/hog2", "trunk/scenarios/rooms/32room_000.map.scen", "c3a772f2db93", "707143ae92ad"),
    "grid_planning/movingai/random/random512-10-0.map": (262_693, "df47a4030f8967d8be60b33fecd1f6aa059132a2fe1e1b19e463dc52c0838654",
        "nathansttt/hog2", "maps/random/random512-10-0.map", "70842df4bb97", "51de9e11625a"),
    "grid_planning/movingai/random/random512-10-0.map.scen": (108_773, "96b7442d102d5dd7ede55d817f434d791dd93f2eb82196234f43d702e5ff8832",
        "nathansttt/hog2", "trunk/scenarios/random/random512-10-0.map.scen", "c3a772f2db93", "6db2d6b116b4"),
    "grid_planning/movingai/maze/maze512-32-9.map": (262_693, "214de410a56a97c2477e827e4eaf15baf183f46555f3e62a13d106bbc98b3a1a",
        "THeK3nger/movingai-rust", "tests/maze512-32-9.map", "78ceba7fd281", "222fd9cbb2ad"),
    "grid_planning/movingai/maze/maze512-32-9.map.scen": (462_285, "1c7b51a3ee6fe4d79db9c878e5529f477bb866187634a9f1b15e9de901fabbf5",
        "THeK3nger/movingai-rust", "tests/maze512-32-9.map.scen", "78ceba7fd281", "22b2e052cea1"),
    "lidar_2d/intel.clf.bz2": (2_277_279, "d9ce4addefc9405d5e78fd883d2214766552537d262009f8e6f0137885f9f72a",
        "MOLAorg/mola_test_datasets", "datasets/radish/intel.clf.bz2", "13a2ed141116", "cecd24be8927"),
    "lidar_2d/intel.relations": (265_713, "330378f153eeae652d6756c1746f335801f66c3e097d90611548e6c4f593c359",
        "xiaofeng419/SLAM-2D-LIDAR-SCAN", "DataSet/RawData/intel.relations", "d469252f5b33", ""),
    "lidar_2d/fr079.clf.bz2": (1_522_745, "9c3930e17957889c24986390dc7fe3eeddd3d7019a8172085dbed8a28a0e6b77",
        "MOLAorg/mola_test_datasets", "datasets/radish/fr079.clf.bz2", "13a2ed141116", "8301cf13d4d8"),
    "lidar_2d/fr079.relations": (133_044, "7e7f06b4aca455cb68f1f23d04e7c7316c5e17773e872734c860ed7a274cdfc7",
        "xiaofeng419/SLAM-2D-LIDAR-SCAN", "DataSet/RawData/fr079.relations", "d469252f5b33", ""),
    "lidar_2d/mit-csail.clf.bz2": (539_615, "e010703e450a20e71a97b0e8de88d9474040c8106e547ff894d885e67a309b47",
        "MOLAorg/mola_test_datasets", "datasets/radish/mit-csail.clf.bz2", "13a2ed141116", "cbb019a9b55e"),
    "lidar_2d/fr-clinic_robotlaser.clf.bz2": (1_719_679, "f1123753be7308178547d487df96dfc230669a55c21253c3225c7627b124d6d8",
        "MOLAorg/mola_test_datasets", "datasets/radish/fr-clinic_robotlaser.clf.bz2", "13a2ed141116", "e684a099abec"),
    "vision/kitti_vo_a/poses.txt": (8_205, "da9f1248f88cc264d995a2890e6e78d0432d73e982420000345aeae47147e8ab",
        "niconielsen32/ComputerVision", "VisualOdometry/KITTI_sequence_1/poses.txt", "37b279fa44e2", ""),
    "vision/kitti_vo_a/calib.txt": (456, "6935f9fa72a67b60a89277d3044e4a164c507156de37b0a55212f08bbb551fc1",
        "niconielsen32/ComputerVision", "VisualOdometry/KITTI_sequence_1/calib.txt", "37b279fa44e2", ""),
    "reference_trajectories/KITTI_00_gt.txt": (728_871, "90791a4113df979b149fa9e1104e960ea59f525a8318a202dbb6aec1a3d88793",
        "MichaelGrupp/evo", "test/data/KITTI_00_gt.txt", "26d0953d4da0", ""),
    "reference_trajectories/KITTI_00_gt_times.txt": (59_033, "99a2899466cdc28dd292b4856d214a8b0aab035b91b02bb6afcb4ff363e7d421",
        "MichaelGrupp/evo", "test/data/KITTI_00_gt_times.txt", "26d0953d4da0", ""),
    "reference_trajectories/KITTI_00_ORB.txt": (689_230, "13437093039ccd585d03feb327a6f809a5e12a05a3be33d26192025411eded10",
        "MichaelGrupp/evo", "test/data/KITTI_00_ORB.txt", "26d0953d4da0", ""),
    "reference_trajectories/V101_gt.txt": (239_010, "6d2f961334ff3069105be0aacf118d3c7e82bf3ab0e238acd5f40f1d897573d1",
        "MichaelGrupp/evo", "test/data/V101_gt.txt", "19ba625c3ddb", ""),
    "reference_trajectories/V101_openvins.txt": (564_165, "1d2b1985115366dc825f7411c13d3fa1c2ff5abca7bf3ff26bca0390717ea50e",
        "MichaelGrupp/evo", "test/data/V101_openvins.txt", "19ba625c3ddb", ""),
    "reference_trajectories/freiburg1_xyz-groundtruth.txt": (201_100, "aac0319a6ef4e1cdf61e779d2152b95aa7e9f7b1749d6d18717b43ddabffede2",
        "MichaelGrupp/evo", "test/data/freiburg1_xyz-groundtruth.txt", "26d0953d4da0", ""),
    "reference_trajectories/freiburg1_xyz-rgbdslam.txt": (65_489, "bbcd66c6e19e6037ee550c66d307c9a008ed29ef8bd9baa6bbda119a1a51a3ee",
        "MichaelGrupp/evo", "test/data/freiburg1_xyz-rgbdslam.txt", "26d0953d4da0", ""),
    "maps_ros/willow-2010-02-18-0.10.pgm": (344_182, "d7644ea5eabbbc77dcb6f136774f9b159a6514151f9c411bbd6c383f592bd6e0",
        "turtlebot/turtlebot_apps", "turtlebot_navigation/maps/willow-2010-02-18-0.10.pgm", "4bbafc7bfdfc", ""),
    "maps_ros/willow-2010-02-18-0.10.yaml": (145, "e10d1ba93e8f204a581641a5da85d6803c89c4216e619637a2fcfe0317d290af",
        "turtlebot/turtlebot_apps", "turtlebot_navigation/maps/willow-2010-02-18-0.10.yaml", "4bbafc7bfdfc", ""),
}

#: files of the gtsam 4.3.0 wheel's Data folder we register: name -> (bytes, sha256 of the wheel's
#: copy, a borglab/gtsam commit whose examples/Data holds a file of that name, or None when our
#: code index had none -- then the source is the unpinned 'develop' branch and only the sha256 pins
#: the content)
WHEEL_FILES: dict[str, tuple[int, str, str | None]] = {
    "VO_calibration00s.txt": (50, "3ddfb990bab2b301b86c332582ea6425a17a4ef2664957062c8089bf997012e6", None),
    "VO_camera_poses00s.txt": (15_053, "062c876b63746eb748b069628fbe9144533d904dcec79fe05874db1ffd85dcff", None),
    "VO_stereo_factors00s.txt": (3_030_190, "e66b9ce0cc4bee456961164a1c9a5e59b229675ef4610f2cc4932391c5a4fd1d", None),
    "eqvio_processed_30s.csv": (2_665_606, "3b62cc8093e2cbb081460abfffba663a61a5a9702a382acc3a583c5d056e27af", None),
    "w20000.txt": (1_867_785, "9690b10bc2c7f2cebfb1969dd1643b5813aa3db50b40d98685c36c4eeae69c57", "c24a2c9845993f43e70032d1cdcb76befd9c5069"),
    "sphere2500.txt": (618_297, "4b9418a300e6ec3ec0a4223e13b0febb068d18f9a008ebb59c1b9f262626e552", "e39dd5901ce34c9c4a31a178fc4848ec6036ff15"),
    "sphere2500_groundtruth.txt": (633_111, "b9cfd29c951586bf9afc09bb8f88bf67b7436e6c988a3e208e126e7d77b4520a", "198279f4ff47fad3a8861c664a5bf6185c51e401"),
    "sphere_smallnoise.graph": (793_977, "5087ee16e462cdd80d4a1f422df48fdfec8586607180ae78971ace97f31efc09", "9c8377f47619d8da252fe6f49e6cbb53855af70d"),
    "victoria_park.txt": (685_277, "10596bac625acfe009080748b0ec9993fc9925a93370878c20288a22eeee5253", "5f9564dfb99e23365790c46a843c826495c8a914"),
    "victoriaPark_reduced_1k.g2o": (98_539, "468cbee16c3d0168653af6e2e8b5d24344a6b17d74781d11e0c93e6deb6f6809", "224032394f3b5e42cdb57b39b56c75af298ebe0e"),
    "w100_30.g2o": (4_243, "69d9959b6e6c530ad268b4d9999383acbd262b54319fd830e1d3075142c73343", "71a4b7689367849223ff26662606527b59e1dbf2"),
    "toyExample.g2o": (869, "d3f97f27670fd890c6c53a8c58f0a12e53417a4c7198dcf84d425892eba820b9", "d5f256f3e2e1dac38ab31fde8a688679654cfc4e"),
    "pose2example.txt": (1_632, "578f33a41273d7e7be0bd542e9a6bc8963bbb86c33891f4851d07b633035ec8f", "94fcf691062b19700bbc95f68d12dc03737c851e"),
    "pose3example.txt": (2_282, "bd92c6ed222b75769c1301aae1290af66ea6172ac3266b341697980a4976eebb", "495fe90a41b8dc0f4aa9c78af59fbc2f22e5e0e6"),
    "pose3example-grid.txt": (8_482, "8b4223efe214fcc2cdcd0cfabfcc8b85e957b8afb9119657477ca8ad96b9208c", "94fcf691062b19700bbc95f68d12dc03737c851e"),
    "pose3example-offdiagonal.txt": (471, "13311fab15d7c419071d6085c94104484998ec95769e29124f94ef555b37347a", "a9e3545a2938b79cf58be49f90a563b3188decaa"),
    "pose3Localizationexample.txt": (1_658, "74dceb38b90c2259174a3e2006350b84dda954467cece231f77f3de50e015014", "4307cc85b9cb271a501799a1ea36bfad1da48714"),
    "ISAM2_GT_city10000.txt": (216_006, "a300f29b446608ea1c0175b5a7463584b82200196ebf0ac24cf1291744f97eb2", "c98e4a79624eab18789dd3236c2fbbd0ca428ca5"),
    "T1_city10000_04.txt": (1_061_154, "7899a7b4a8cc63194269ca4cea1a5b002073a2e8a34f8d2ce88e75e92ec90add", "20543c955cfae31b959364989ede293c33e9864e"),
    "cityTrees_reduced_1k.g2o": (79_798, "d26aa4d25e4be023aa97b2c3fe121ddd43836888b54daa3d00bbc3c31c7336c5", "71a25ca36c084cbad1f872e812d6d97fbadfdb05"),
    "example.graph": (33_069, "388ea4254a2f999d63323051d1e11922dbcfa9c0703d180fa38df39ce3f46247", "e39dd5901ce34c9c4a31a178fc4848ec6036ff15"),
    "Klaus3.g2o": (1_235, "28a134d684e53ae7d60cebb4c02a75897f01b561d2958dcdd1d2a07741d9be29", "6800c4c7fe3f668f3288378a8a87866bda512af9"),
    "noisyToyGraph.txt": (637, "9b2d2930cf50b2b2c756172f50c34503c41644e529727bd7a4960f6e785ff859", "0ed343723f81509a90d2259699e9614fd1d7c669"),
    "goats_15.pyfg": (141_444, "ed7c78b5070c305d3a08a6a1811c33800c732e851d9d6272372ce22632c68bba", "71a25ca36c084cbad1f872e812d6d97fbadfdb05"),
    "goats_16.pyfg": (73_210, "b2c24d1da15f4ee4ef3308e80ae63b43a6adc4d6e548e4174457994e10ff62e5", "71a4b7689367849223ff26662606527b59e1dbf2"),
    "Plaza1_.mat": (677_168, "9ccbfec19942eabecfa3206bff983bf708b98d6c7db462d81c55376f92d75847", "123657e3d06f91927096e95f27364ded8113ea6e"),
    "Plaza2_.mat": (296_733, "72f0abe0fea2050eb5ee1cffc8c43823266a35785b7cdecac4ec5eae727561a2", "123657e3d06f91927096e95f27364ded8113ea6e"),
    "Plaza1_DR.txt": (772_560, "41233e2e97d482c12a6cd074583c15fb47918d015a3d59e90d8b3b3cfba8b09d", "c24a2c9845993f43e70032d1cdcb76befd9c5069"),
    "Plaza1_TD.txt": (374_074, "56b6cdd86327da38143c0f2b2a3e4337908e1d3447c32b2897005ebbd3326be8", "2efc4294b82c5593dbc524ef32fa8def896ba663"),
    "Plaza2_DR.txt": (327_200, "afd63364d0650e90ca1a9f13ceb9105104f52ab6768beb1cdf584ab9aada024e", "123657e3d06f91927096e95f27364ded8113ea6e"),
    "Plaza2_TD.txt": (192_496, "05e884e9e131b805db71bacd345b8606e8d53fe21a6b5a3acbbb4f33d0a68cfd", "c24a2c9845993f43e70032d1cdcb76befd9c5069"),
    "w100.graph": (20_262, "00e68e8ba3985213814862f53a533916a005c2b40d374d840f6d069d91abaa06", None),
    "KittiEquivBiasedImu.txt": (6_648_928, "90264418a69979eccd6d84eb69560225dff544bf6affe353ea37bb70d4ecf38a", None),
    "KittiEquivBiasedImu_metadata.txt": (221, "70f51ea40a05f1097484634d60064f16bc1622abcaa872458e555442afa44580", None),
    "KittiGps_converted.txt": (42_122, "aa6f2a1332a40e8cbcd071de650f6b62fc58253e8bef83c8efeb51548dc9102c", None),
    "w10000.graph": (4_203_673, "1e88f220bd580a4c2b9fc065358608a53b26b1c30033405990b4cdc83236fc89", None),
}

#: MANIFEST 'gtsam local check' lines (NOT published values): file name ->
#: (edges, poses, init, optimizer, gtsam error at optimum, chi2 as printed, iterations, seconds,
#: SE-Sync F at that optimum or None)
GTSAM_LOCAL_CHECKS: dict[str, tuple[int, int, str, str, float, float, int, float, float | None]] = {
    "intel.g2o": (2512, 1728, "file", "LM", 22.5021, 45.0042, 4, 0.166, 54.5039),
    "input_INTEL_g2o.g2o": (1483, 1228, "file", "DL-QR", 107.919, 215.838, 20, 0.856, None),
    "intel_g2o_943.g2o": (1837, 943, "file", "LM", 273.232, 546.463, 4, 0.062, None),
    "input_MITb_g2o.g2o": (827, 808, "file", "LM", 385.119, 770.239, 32, 0.215, 1360.85),
    "CSAIL.g2o": (1172, 1045, "file", "LM", 20.2754, 40.5509, 5, 0.049, 53.4863),
    "CSAIL_P_toro.graph": (1172, 1045, "file", "LM", 19.5641, 39.1281, 6, 0.058, None),
    "FR079_P_toro.graph": (1217, 989, "file", "LM", 18.7859, 37.5718, 5, 0.05, None),
    "FRH_P_toro.graph": (2820, 1316, "file", "LM", 9.65684e-05, 0.000193137, 3, 0.077, None),
    "manhattan.g2o": (5453, 3500, "file", "LM", 1774.52, 3549.04, 5, 0.29, 6610.21),
    "input_M3500_g2o.g2o": (5453, 3500, "file", "LM", 68.9574, 137.915, 6, 0.868, None),
    "input_M3500b_g2o.g2o": (5453, 3500, "file", "LM", 4117.64, 8235.27, 977, 158.27, None),
    "manhattanOlson3500.g2o": (5598, 3500, "file", "LM", 73.0394, 146.079, 6, 0.313, None),
    "city10000.g2o": (20687, 10000, "file", "LM", 255.994, 511.987, 7, 1.386, 649.359),
    "ais2klinik.g2o": (16727, 15115, "file", "LM", 86.4065, 172.813, 251, 79.542, 195.069),
    "ring.g2o": (459, 434, "file", "LM", 5.58155, 11.1631, 6, 0.062, None),
    "ringCity.g2o": (3261, 2361, "file", "LM", 131.409, 262.818, 13, 0.717, None),
    "kitti_00.g2o": (4677, 4541, "file", "LM", 49.1611, 98.3221, 4, 0.224, None),
    "kitti_02.g2o": (4703, 4661, "file", "LM", 39.3823, 78.7646, 5, 0.309, None),
    "kitti_05.g2o": (2826, 2761, "file", "LM", 78.5519, 157.104, 4, 0.109, None),
    "kitti_06.g2o": (1150, 1101, "file", "LM", 12.9735, 25.947, 3, 0.039, None),
    "kitti_07.g2o": (1106, 1101, "file", "LM", 6.33052, 12.661, 3, 0.086, None),
    "kitti_08.g2o": (4070, 4071, "file", "LM", 1.41187e-21, 2.82373e-21, 0, 0.534, None),
    "kitti_09.g2o": (1592, 1591, "file", "LM", 17.1914, 34.3828, 4, 0.127, None),
    "sphere2500.g2o": (4949, 2500, "file", "LM", 675.701, 1351.4, 7, 0.853, 1729.98),
    "torus3D.g2o": (9048, 5000, "chordal", "LM", 12117.6, 24235.3, 5, 4.874, 24227),
    "parking-garage.g2o": (6275, 1661, "file", "LM", 0.634192, 1.26838, 8, 0.686, 1.26608),
    "cubicle.g2o": (16869, 5750, "file", "LM", 1372.78, 2745.56, 40, 27.243, 2568.36),
    "sphere_bignoise_vertex3.g2o": (8647, 2200, "chordal", "LM", 1.49417e+06, 2.98834e+06, 5, 0.848, None),
    "smallGrid3D.g2o": (297, 125, "chordal", "LM", 517.925, 1035.85, 7, 0.045, None),
    "tinyGrid3D.g2o": (11, 9, "chordal", "LM", 9.31391, 18.6278, 7, 0.001, None),
}

# --- licences, quoted from the source repositories (see MANIFEST.md) -------------------------

LIC_SESYNC = ("LGPL-3.0 (david-m-rosen/SE-Sync; covers the code, no separate data licence). Data originally "
              "from L. Carlone's dataset page (lucacarlone.mit.edu/datasets, 'please cite'), iSAM, g2o, Vertigo.")
LIC_DPGO = ("MIT (mit-acl/dpgo; code, no separate data licence). Data from lucacarlone.mit.edu/datasets "
            "(cite Carlone et al., ICRA 2015).")
LIC_NANOPGO = ("No licence file (gisbi-kim/nano-pgo); README: datasets from lucacarlone.mit.edu/datasets, "
               "which only asks for citation.")
LIC_G2O = "LGPL-3.0 (g2o README: 'g2o is licensed under LGPL version 3'); data shipped with g2o."
LIC_VERTIGO = ("GPL-3.0-or-later (Vertigo README); datasets provided by / reproduced from Olson, g2o, iSAM.")
LIC_KITTI = ("CC BY-NC-SA 3.0 -- derived from KITTI: NON-COMMERCIAL use only, share alike. Repository: "
             "LGPL-3.0 (SE-Sync) or MIT (mit-acl/dpgo) for the code.")
LIC_ISAM = "LGPL-2.1 (rickytan/iSAM, mirror of the iSAM 1.7 release by Kaess et al., including data/)."
LIC_MRCLAM = ("No licence file (curow/multi-robot-localization). The UTIAS MRCLAM page asks to cite Leung, "
              "Halpern, Barfoot, Liu, IJRR 2011; no redistribution restriction found.")
LIC_CORA = ("No licence file (MarineRoboticsGroup/cora); README asks to cite Papalia et al., 'Certifiably "
            "Correct Range-Aided SLAM'. Derived from UTIAS MRCLAM.")
LIC_MOVINGAI = ("MIT (c) 2015 Nathan Sturtevant (nathansttt/hog2 LICENSE.txt). movingai.com asks to cite "
                "Sturtevant 2012, IEEE TCIAIG 4(2):144-148.")
LIC_MOVINGAI_RUST = ("MIT (c) 2018 Davide Aversa (THeK3nger/movingai-rust; test files copied from "
                     "movingai.com). Cite Sturtevant 2012, IEEE TCIAIG 4(2):144-148.")
LIC_GTSAM = ("BSD-3-Clause (GTSAM; file shipped in the gtsam wheel's Data folder). Cite the original "
             "dataset authors.")

SESYNC_PAPER = ("Rosen, Carlone, Bandeira, Leonard, 'SE-Sync: A certifiably correct algorithm for "
                "synchronization over the special Euclidean group', IJRR 38(2-3):95-125, 2019")

# --- reference values --------------------------------------------------------------------------
# Each reference: (kind, value, objective, published, source). Objectives: 'sesync_F' (SE-Sync's
# objective, see MANIFEST "Conventions"), 'chi2' (sum e^T Omega e), 'gtsam_error' (1/2 chi2).


def sesync(fstar: float, table: int = 1) -> tuple:
    return ("sesync_fstar", fstar, "sesync_F", True,
            f"{SESYNC_PAPER}, Table {table} (certified global optimum, 4 significant digits)")

LIC_RADISH = ("CC-BY-3.0 (Freiburg SLAM-evaluation page; MOLAorg/mola_test_datasets datasets/radish README and "
              "LICENSE). Cite Kuemmerle et al., 'On measuring the accuracy of SLAM algorithms', Autonomous Robots 2009.")
LIC_EVO_DATA = ("evo's test data (MichaelGrupp/evo, GPL-3.0 repository); the trajectories keep their datasets' "
                "terms: KITTI CC BY-NC-SA 3.0 (non-commercial), EuRoC research terms, TUM RGB-D CC BY 4.0.")
LIC_KITTI_IMAGES = ("CC BY-NC-SA 3.0 (KITTI; NON-COMMERCIAL). Copied from niconielsen32/ComputerVision "
                    "VisualOdometry/KITTI_sequence_1, which states no licence of its own.")
LIC_WILLOW = "BSD (turtlebot/turtlebot_apps package.xml)."


# --- the datasets ---------------------------------------------------------------------------
# name -> dict(kind, format, files (registry-relative; 'gtsam_data/<name>' for wheel files;
# the first file is the primary one), title, licence, counts, refs, ground_truth
# (file, format) or None, notes). Ground-truth formats: 'id_x_y_theta', 'x_y_theta' (line k =
# pose k), 'isam_noise_free' (compose the noise-free edges of an iSAM file).

ENTRIES: dict[str, dict] = {
    # ---- 2D pose graphs (../shared/datasets) ----
    "intel": dict(
        kind="pose_graph_2d", format="g2o", files=["pose_graph_2d/intel.g2o"],
        title="Intel Research Lab (Seattle), SE-Sync version", licence=LIC_SESYNC,
        counts=dict(poses=1728, edges=2512, loop_closures=785),
        refs=[sesync(52.35),
              ("sesync_F_notebook", 52.3482, "sesync_F", True,
               "stored output of david-m-rosen/SE-Sync C++/examples/PySESync.ipynb (tr(Lambda) = 52.3455, gap 0.00274)")]),
    "intel-carlone": dict(
        kind="pose_graph_2d", format="g2o", files=["pose_graph_2d/input_INTEL_g2o.g2o"],
        title="Intel Research Lab, Carlone's input_INTEL_g2o", licence=LIC_DPGO,
        counts=dict(poses=1228, edges=1483, loop_closures=256),
        refs=[("chi2_optimum", 215.8405, "chi2", True,
               "JeffLIrion/python-graphslam README (same bytes): chi2 7,191,686.3825 -> 215.8405 in 6 Gauss-Newton iterations")],
        notes="Information spans 10 to 2.7e12: gtsam LM with Cholesky fails; use dog-leg with MULTIFRONTAL_QR."),
    "intel-g2o": dict(
        kind="pose_graph_2d", format="g2o", files=["pose_graph_2d/intel_g2o_943.g2o"],
        title="Intel Research Lab, original g2o / Vertigo version (intel.g2o)", licence=LIC_G2O,
        counts=dict(poses=943, edges=1837, loop_closures=895)),
    "mit": dict(
        kind="pose_graph_2d", format="g2o", files=["pose_graph_2d/input_MITb_g2o.g2o"],
        title="MIT Killian Court (MITb)", licence=LIC_DPGO,
        counts=dict(poses=808, edges=827, loop_closures=20),
        notes="Poor initial estimate (gtsam initial error 3.5e9); no published optimum."),
    "csail": dict(
        kind="pose_graph_2d", format="g2o", files=["pose_graph_2d/CSAIL.g2o"],
        title="MIT CSAIL building, SE-Sync version (no VERTEX lines)", licence=LIC_SESYNC,
        counts=dict(poses=1045, edges=1172, loop_closures=128), refs=[sesync(31.70)],
        notes="No vertices: initial poses chained from edges. One duplicated pose pair."),
    "csail-toro": dict(
        kind="pose_graph_2d", format="toro", files=["pose_graph_2d/CSAIL_P_toro.graph"],
        title="MIT CSAIL building, Carlone's TORO version", licence=LIC_NANOPGO,
        counts=dict(poses=1045, edges=1172)),
    "fr079": dict(
        kind="pose_graph_2d", format="toro", files=["pose_graph_2d/FR079_P_toro.graph"],
        title="Freiburg building 079", licence=LIC_NANOPGO, counts=dict(poses=989, edges=1217)),
    "frh": dict(
        kind="pose_graph_2d", format="toro", files=["pose_graph_2d/FRH_P_toro.graph"],
        title="Freiburg University Hospital (fr-clinic)", licence=LIC_NANOPGO,
        counts=dict(poses=1316, edges=2820), notes="Initial estimate already near-optimal."),
    "manhattan": dict(
        kind="pose_graph_2d", format="g2o", files=["pose_graph_2d/manhattan.g2o"],
        title="Olson's Manhattan world M3500, SE-Sync version (no VERTEX lines)", licence=LIC_SESYNC,
        counts=dict(poses=3500, edges=5453, loop_closures=1954), refs=[sesync(6432.0)]),
    "m3500": dict(
        kind="pose_graph_2d", format="g2o", files=["pose_graph_2d/input_M3500_g2o.g2o"],
        title="M3500, Carlone's version (isotropic information)", licence=LIC_DPGO,
        counts=dict(poses=3500, edges=5453)),
    "m3500b": dict(
        kind="pose_graph_2d", format="g2o", files=["pose_graph_2d/input_M3500b_g2o.g2o"],
        title="M3500b: M3500 with 0.2 rad extra rotation noise", licence=LIC_NANOPGO,
        counts=dict(poses=3500, edges=5453),
        notes="Hard: local minima; the local check (977 LM iterations) is the best found, not certified."),
    "manhattan-olson": dict(
        kind="pose_graph_2d", format="g2o",
        files=["pose_graph_2d/manhattanOlson3500.g2o", "pose_graph_2d/manhattanOlson3500_groundtruth_nodes.dat"],
        title="Olson's Manhattan world, original 5598-edge g2o file, with ground truth",
        licence=f"{LIC_G2O} Ground truth: {LIC_VERTIGO}",
        counts=dict(poses=3500, edges=5598, loop_closures=2099),
        ground_truth=("pose_graph_2d/manhattanOlson3500_groundtruth_nodes.dat", "x_y_theta")),
    "city10000": dict(
        kind="pose_graph_2d", format="g2o",
        files=["pose_graph_2d/city10000.g2o", "gtsam_data/ISAM2_GT_city10000.txt"],
        title="City10000 (Johannsson & Kaess), ground truth from the gtsam wheel", licence=LIC_SESYNC,
        counts=dict(poses=10000, edges=20687, loop_closures=10688), refs=[sesync(638.6)],
        ground_truth=("gtsam_data/ISAM2_GT_city10000.txt", "x_y_theta"),
        notes="Ground truth verified (MANIFEST) to equal the composed noise-free iSAM odometry to < 5 mm."),
    "ais2klinik": dict(
        kind="pose_graph_2d", format="g2o", files=["pose_graph_2d/ais2klinik.g2o"],
        title="Freiburg AIS -> clinic", licence=LIC_SESYNC,
        counts=dict(poses=15115, edges=16727, loop_closures=1614), refs=[sesync(188.5)]),
    "ring": dict(
        kind="pose_graph_2d", format="g2o",
        files=["pose_graph_2d/ring.g2o", "pose_graph_2d/ring_groundtruth_poses.txt"],
        title="Vertigo synthetic ring, with ground truth", licence=LIC_VERTIGO,
        counts=dict(poses=434, edges=459),
        ground_truth=("pose_graph_2d/ring_groundtruth_poses.txt", "id_x_y_theta")),
    "ringcity": dict(
        kind="pose_graph_2d", format="g2o",
        files=["pose_graph_2d/ringCity.g2o", "pose_graph_2d/ringCity_groundtruth_poses.txt"],
        title="Vertigo synthetic ringCity, with ground truth", licence=LIC_VERTIGO,
        counts=dict(poses=2361, edges=3261),
        ground_truth=("pose_graph_2d/ringCity_groundtruth_poses.txt", "id_x_y_theta")),
    **{f"kitti_{k}": dict(
        kind="pose_graph_2d", format="g2o", files=[f"pose_graph_2d_kitti/kitti_{k}.g2o"],
        title=f"KITTI odometry sequence {k} as a 2D pose graph (no VERTEX lines)", licence=LIC_KITTI,
        counts=dict(poses=p, edges=e, loop_closures=lc),
        notes="NON-COMMERCIAL (KITTI CC BY-NC-SA 3.0)." + (" No loop closures: the initial estimate is optimal." if lc == 0 else ""))
       for k, p, e, lc in [("00", 4541, 4677, 137), ("02", 4661, 4703, 43), ("05", 2761, 2826, 66),
                           ("06", 1101, 1150, 50), ("07", 1101, 1106, 6), ("08", 4071, 4070, 0),
                           ("09", 1591, 1592, 2)]},
    # ---- 3D pose graphs ----
    "sphere2500": dict(
        kind="pose_graph_3d", format="g2o",
        files=["pose_graph_3d/sphere2500.g2o", "gtsam_data/sphere2500_groundtruth.txt"],
        title="Kaess' sphere2500 (g2o version), ground truth from the gtsam wheel", licence=LIC_SESYNC,
        counts=dict(poses=2500, edges=4949, loop_closures=2450), refs=[sesync(1687.0, 2)],
        ground_truth=("gtsam_data/sphere2500_groundtruth.txt", "isam_noise_free")),
    "torus3d": dict(
        kind="pose_graph_3d", format="g2o", files=["pose_graph_3d/torus3D.g2o"],
        title="Torus3D", licence=LIC_SESYNC, counts=dict(poses=5000, edges=9048, loop_closures=4049),
        refs=[sesync(24230.0, 2)],
        notes="Use chordal initialisation: LM from the file's vertices stops in a local minimum (error 29950)."),
    "parking-garage": dict(
        kind="pose_graph_3d", format="g2o", files=["pose_graph_3d/parking-garage.g2o"],
        title="Parking garage (real, multi-level)", licence=LIC_SESYNC,
        counts=dict(poses=1661, edges=6275, loop_closures=4615),
        refs=[sesync(1.263, 2),
              ("chi2_optimum", 1.2387, "chi2", True,
               "JeffLIrion/python-graphslam README (same bytes): chi2 16,720.0210 -> 1.2387 in 4 Gauss-Newton iterations")]),
    "cubicle": dict(
        kind="pose_graph_3d", format="g2o", files=["pose_graph_3d/cubicle.g2o"],
        title="Cubicle (real office, largely planar)", licence=LIC_SESYNC,
        counts=dict(poses=5750, edges=16869), refs=[sesync(717.1, 2)],
        notes="5,021 edges have non-positive-definite information (read with policy 'keep' by default); "
              "chordal initialisation fails; f* is not comparable to gtsam's optimum here."),
    "sphere-bignoise": dict(
        kind="pose_graph_3d", format="g2o", files=["pose_graph_3d/sphere_bignoise_vertex3.g2o"],
        title="Grisetti's high-noise sphere (sphere-a)", licence=LIC_SESYNC, counts=dict(poses=2200, edges=8647),
        notes="Very hard from the file's vertices; use chordal initialisation."),
    "smallgrid3d": dict(
        kind="pose_graph_3d", format="g2o", files=["pose_graph_3d/smallGrid3D.g2o"],
        title="Small synthetic 3D grid", licence=LIC_SESYNC, counts=dict(poses=125, edges=297)),
    "tinygrid3d": dict(
        kind="pose_graph_3d", format="g2o", files=["pose_graph_3d/tinyGrid3D.g2o"],
        title="Tiny synthetic 3D grid", licence=LIC_SESYNC, counts=dict(poses=9, edges=11)),
    "sphere400": dict(
        kind="pose_graph_3d", format="isam", files=["pose_graph_3d/sphere400.txt"],
        title="Kaess' small sphere (iSAM text, square-root information)", licence=LIC_ISAM,
        counts=dict(poses=400, edges=779, loop_closures=380)),
    # ---- landmark SLAM ----
    "citytrees10000": dict(
        kind="landmark_2d", format="isam",
        files=["landmark_2d/cityTrees10000.txt", "landmark_2d/cityTrees10000_groundtruth.txt"],
        title="cityTrees10000 (iSAM): poses + point landmarks, with noise-free twin", licence=LIC_ISAM,
        counts=dict(poses=10000, edges=9999, landmarks=100, landmark_measurements=4443),
        ground_truth=("landmark_2d/cityTrees10000_groundtruth.txt", "isam_noise_free")),
    "mrclam1": dict(
        kind="landmark_2d", format="mrclam",
        files=["landmark_2d/MRCLAM_Dataset1/Robot1_Odometry.dat", "landmark_2d/MRCLAM_Dataset1/Robot1_Measurement.dat",
               "landmark_2d/MRCLAM_Dataset1/Landmark_Groundtruth.dat", "landmark_2d/MRCLAM_Dataset1/Barcodes.dat"],
        title="UTIAS MRCLAM Dataset1, robot 1 (raw odometry and range-bearing; no robot ground truth)",
        licence=LIC_MRCLAM,
        counts=dict(odometry_rows=97890, measurements=5723, landmarks=15),
        notes="Robot1_Groundtruth.dat is NOT included (> 4 MiB in every mirror); landmark ground truth is."),
    "mrclam5a": dict(
        kind="landmark_2d", format="pyfg", files=["landmark_2d/mrclam5a.pyfg"],
        title="MRCLAM 5a in PyFG format (CORA): 5 robots, Vicon-derived vertex values", licence=LIC_CORA,
        counts=dict(poses=1080, landmarks=15, odometry_edges=1075, landmark_edges=1127, range_edges=316),
        notes="VERTEX values are interpolated Vicon ground truth."),
    "torus2000points": dict(
        kind="landmark_3d", format="isam", files=["landmark_3d/torus2000Points.txt"],
        title="Kaess' torus with 3D point landmarks (iSAM)", licence=LIC_ISAM,
        counts=dict(poses=1073, edges=2034, landmarks=20, landmark_measurements=1039)),
    # ---- grid planning (MovingAI map + scenario pairs) ----
    **{name.lower(): dict(
        kind="grid_map", format="movingai", files=[f"grid_planning/movingai/{folder}/{name}.map",
                                                   f"grid_planning/movingai/{folder}/{name}.map.scen"],
        title=f"MovingAI {folder} map {name} with its scenarios", licence=lic, counts=counts,
        refs=[("scenario_optimal_lengths", None, "path_length", True,
               "the optimal_length column of the .scen file (Sturtevant 2012); 8-connected, no corner cutting")])
       for folder, name, lic, counts in [
           ("dao", "arena", LIC_MOVINGAI, dict(width=49, height=49, free_cells=2054, scenarios=160)),
           ("dao", "den312d", LIC_MOVINGAI, dict(width=81, height=65, free_cells=2445, scenarios=320)),
           ("dao", "den520d", LIC_MOVINGAI, dict(width=257, height=256, free_cells=28178, scenarios=888)),
           ("dao", "brc202d", LIC_MOVINGAI, dict(width=481, height=530, free_cells=43151, scenarios=2519)),
           ("street", "Berlin_0_256", LIC_MOVINGAI + " OSM-derived: (c) OpenStreetMap contributors (ODbL).",
            dict(width=256, height=256, scenarios=930)),
           ("street", "Boston_0_256", LIC_MOVINGAI + " OSM-derived: (c) OpenStreetMap contributors (ODbL).",
            dict(width=256, height=256, scenarios=950)),
           ("room", "8room_000", LIC_MOVINGAI, dict(width=512, height=512, scenarios=1940)),
           ("room", "32room_000", LIC_MOVINGAI, dict(width=512, height=512, scenarios=1900)),
           ("random", "random512-10-0", LIC_MOVINGAI, dict(width=512, height=512, scenarios=1670)),
           ("maze", "maze512-32-9", LIC_MOVINGAI_RUST, dict(width=512, height=512, scenarios=8010)),
       ]},
    # ---- the gtsam wheel's Data folder ----
    "w100": dict(
        kind="pose_graph_2d", format="toro", files=["gtsam_data/w100.graph"],
        title="TORO's small Manhattan world (100 poses)", licence=LIC_GTSAM,
        counts=dict(poses=100, edges=300), notes="40 EQUIV lines, ignored as gtsam.load2D does."),
    "w10000": dict(
        kind="pose_graph_2d", format="toro", files=["gtsam_data/w10000.graph"],
        title="TORO w10000-odom Manhattan world (= M10000)", licence=LIC_GTSAM,
        counts=dict(poses=10000, edges=64311),
        notes="5,875 EQUIV lines, ignored as gtsam.load2D does. The `slamkit bench pose-graph` file."),
    "w20000": dict(
        kind="pose_graph_2d", format="isam", files=["gtsam_data/w20000.txt"],
        title="Large simulated Manhattan pose graph used by gtsam's timing code", licence=LIC_GTSAM,
        counts=dict(poses=20061, edges=26831, loop_closures=6771),
        notes="iSAM-style EDGE2 lines read as square-root information (3.16228 = sqrt 10); this "
              "interpretation is unverified (gtsam.load2D reads the numbers as given)."),
    "pose2example": dict(
        kind="pose_graph_2d", format="g2o", files=["gtsam_data/pose2example.txt"],
        title="gtsam's tiny 2D pose graph", licence=LIC_GTSAM, counts=dict(poses=11, edges=12)),
    "noisytoygraph": dict(
        kind="pose_graph_2d", format="g2o", files=["gtsam_data/noisyToyGraph.txt"],
        title="gtsam's noisy 2D toy graph", licence=LIC_GTSAM, counts=dict(poses=4, edges=5)),
    "w100_30": dict(
        kind="pose_graph_2d", format="toro_g2o_order", files=["gtsam_data/w100_30.g2o"],
        title="First 30 poses of w100 (VERTEX2/EDGE2 tags with g2o-ordered information)",
        licence=LIC_GTSAM, counts=dict(poses=30, edges=59)),
    "pose3example": dict(
        kind="pose_graph_3d", format="g2o", files=["gtsam_data/pose3example.txt"],
        title="gtsam's tiny 3D pose graph", licence=LIC_GTSAM, counts=dict(poses=5, edges=6)),
    "pose3example-grid": dict(
        kind="pose_graph_3d", format="g2o", files=["gtsam_data/pose3example-grid.txt"],
        title="gtsam's small 3D grid", licence=LIC_GTSAM, counts=dict(poses=27, edges=44)),
    "pose3example-offdiagonal": dict(
        kind="pose_graph_3d", format="g2o", files=["gtsam_data/pose3example-offdiagonal.txt"],
        title="gtsam's one-edge test of off-diagonal information parsing", licence=LIC_GTSAM,
        counts=dict(poses=2, edges=1)),
    "pose3localizationexample": dict(
        kind="pose_graph_3d", format="g2o", files=["gtsam_data/pose3Localizationexample.txt"],
        title="gtsam's tiny 3D localisation example", licence=LIC_GTSAM, counts=dict(poses=5, edges=4)),
    "toyexample": dict(
        kind="pose_graph_3d", format="g2o", files=["gtsam_data/toyExample.g2o"],
        title="gtsam's 3D toy example", licence=LIC_GTSAM, counts=dict(poses=5, edges=6)),
    "klaus3": dict(
        kind="pose_graph_3d", format="g2o", files=["gtsam_data/Klaus3.g2o"],
        title="gtsam's three-pose 3D example (Klaus3)", licence=LIC_GTSAM, counts=dict(poses=3, edges=3)),
    "sphere-smallnoise": dict(
        kind="pose_graph_3d", format="toro", files=["gtsam_data/sphere_smallnoise.graph"],
        title="Low-noise sibling of sphere-bignoise (TORO-3D / HOG-Man)", licence=LIC_GTSAM,
        counts=dict(poses=2200, edges=8647),
        notes="EDGE3 lines carry no information: identity is used (gtsam.load3D cannot read this file)."),
    "sphere2500-isam": dict(
        kind="pose_graph_3d", format="isam",
        files=["gtsam_data/sphere2500.txt", "gtsam_data/sphere2500_groundtruth.txt"],
        title="Kaess' sphere2500 in iSAM format (same measurements as sphere2500), with ground truth",
        licence=LIC_GTSAM, counts=dict(poses=2500, edges=4949),
        ground_truth=("gtsam_data/sphere2500_groundtruth.txt", "isam_noise_free")),
    "city10000-hybrid": dict(
        kind="hybrid_pose_graph_2d", format="gtsam_hybrid_city10000",
        files=["gtsam_data/T1_city10000_04.txt", "gtsam_data/ISAM2_GT_city10000.txt"],
        title="City10000 with ambiguous loop closures (gtsam's hybrid examples)", licence=LIC_GTSAM,
        counts=dict(poses=10000, edges=20687),
        ground_truth=("gtsam_data/ISAM2_GT_city10000.txt", "x_y_theta"),
        notes="Custom 'EDGE2 i 1 j 0 k ...' lines with k hypotheses; not a plain pose graph."),
    "victoria-park": dict(
        kind="landmark_2d", format="gtsam_load2d", files=["gtsam_data/victoria_park.txt"],
        title="Victoria Park (Sydney): odometry + tree landmarks", licence=LIC_GTSAM,
        counts=dict(poses=6969, landmarks=151, landmark_measurements=3640, odometry=6968),
        notes="ODOMETRY/LANDMARK lines with COVARIANCE entries (not iSAM's square-root information): "
              "read with gtsam.load2D."),
    "victoriapark-1k": dict(
        kind="landmark_2d", format="g2o", files=["gtsam_data/victoriaPark_reduced_1k.g2o"],
        title="First 1,000 poses of Victoria Park (EDGE_SE2 + LANDMARK2)", licence=LIC_GTSAM,
        counts=dict(poses=1000, landmarks=48, landmark_measurements=606)),
    "citytrees-1k": dict(
        kind="landmark_2d", format="g2o", files=["gtsam_data/cityTrees_reduced_1k.g2o"],
        title="First 1,000 poses of cityTrees10000 (EDGE_SE2 + LANDMARK2)", licence=LIC_GTSAM,
        counts=dict(poses=1000, landmarks=66, landmark_measurements=406)),
    "example-graph": dict(
        kind="landmark_2d", format="toro", files=["gtsam_data/example.graph"],
        title="gtsam's tiny 2D pose + bearing-range example (VERTEX2/EDGE2 + BR)", licence=LIC_GTSAM,
        counts=dict(poses=95, edges=94, landmarks=24, bearing_range=422)),
    "kitti-imu-gps": dict(
        kind="inertial", format="gtsam_kitti_imu_gps",
        files=["gtsam_data/KittiEquivBiasedImu.txt", "gtsam_data/KittiGps_converted.txt",
               "gtsam_data/KittiEquivBiasedImu_metadata.txt"],
        title="KITTI raw drive IMU (~100 Hz) and GPS (1 Hz, local metric frame) of gtsam's IMUKittiExampleGPS",
        licence=LIC_GTSAM, counts=dict(imu=46968, gps=470, duration_s=471),
        notes="No independent ground truth: score by withholding GPS (slamkit.data.inertial.withhold_gps). "
              "Read by slamkit.data.formats.kitti_imu_gps."),
    "goats15": dict(
        kind="range_slam_2d", format="pyfg", files=["gtsam_data/goats_15.pyfg"],
        title="CORA range-aided SLAM, GOATS 15", licence=LIC_GTSAM,
        counts=dict(poses=473, landmarks=3, range_edges=786)),
    "goats16": dict(
        kind="range_slam_2d", format="pyfg", files=["gtsam_data/goats_16.pyfg"],
        title="CORA range-aided SLAM, GOATS 16", licence=LIC_GTSAM),
    **{f"plaza{k}": dict(
        kind="range_slam_2d", format="plaza",
        files=[f"gtsam_data/Plaza{k}_.mat", f"gtsam_data/Plaza{k}_DR.txt", f"gtsam_data/Plaza{k}_TD.txt"],
        title=f"CMU 'Navigating with ranging radios' Plaza {k}: dead reckoning + UWB ranges", licence=LIC_GTSAM,
        counts=counts, notes="Ground truth is the GT table inside the .mat file (MAT v5).")
       for k, counts in [(1, dict(gt_poses=9658, beacons=4, ranges=3529)),
                         (2, dict(gt_poses=4091, beacons=4, ranges=1816))]},
    # ---- raw 2D laser logs (CARMEN) with the SLAM benchmark's relations ----
    **{f"{name}-log": dict(
        kind="laser_log_2d", format="carmen", files=[f"lidar_2d/{file}"] + ([f"lidar_2d/{rel}"] if rel else []),
        title=title, licence=LIC_RADISH, counts=counts,
        notes=("Relations (t1 t2 x y z roll pitch yaw) are stamped with the FLASER ipc_timestamp. " if rel else
               "No relations are published for this log. ") + "Readings at the maximum range mean no return.")
       for name, file, rel, title, counts in [
           ("intel", "intel.clf.bz2", "intel.relations", "Intel Research Lab (Seattle), raw CARMEN log",
            dict(flaser=13631, odom=26915, relations=2984)),
           ("fr079", "fr079.clf.bz2", "fr079.relations", "Freiburg building 079, raw CARMEN log",
            dict(flaser=4934, odom=8951, relations=1685)),
           ("mit-csail", "mit-csail.clf.bz2", None, "MIT CSAIL, raw CARMEN log", dict(flaser=1988)),
           ("fr-clinic", "fr-clinic_robotlaser.clf.bz2", None, "Freiburg University Hospital, raw CARMEN log (ROBOTLASER1)",
            dict(robotlaser1=6917))]},
    # ---- camera images, reference trajectories, ROS maps (raw recordings, MANIFEST 2026-11-23) ----
    "kitti-vo-a": dict(
        kind="image_sequence", format="kitti_vo",
        files=["vision/kitti_vo_a/poses.txt", "vision/kitti_vo_a/calib.txt"],
        title="51 KITTI odometry frames (left grey, 1226 x 370) with ground-truth poses and calibration",
        licence=LIC_KITTI_IMAGES, counts=dict(frames=51),
        ground_truth=("vision/kitti_vo_a/poses.txt", "kitti"),
        notes="Images in vision/kitti_vo_a/image_l/000000.png .. 000050.png beside poses.txt "
              "(51 files, checksummed together in MANIFEST.md); frames 0.1 s apart; 59.9 m driven."),
    "kitti00-stereo-features": dict(
        kind="stereo_features", format="gtsam_vo",
        files=["gtsam_data/VO_stereo_factors00s.txt", "gtsam_data/VO_camera_poses00s.txt",
               "gtsam_data/VO_calibration00s.txt"],
        title="Real stereo features of the first 77 frames of KITTI odometry 00 (gtsam's StereoVOExample data)",
        licence=LIC_GTSAM, counts=dict(poses=77, stereo_measurements=52544),
        notes="Pose id i is KITTI 00 frame i (id 0 = the origin); each line of the factors "
              "file is 'pose landmark uL uR v X Y Z' with (X, Y, Z) the landmark in that camera's frame. "
              "Read by slamkit.data.formats.gtsam_vo; scored against kitti00-gt beside kitti00-orbslam."),
    "euroc-v101-eqvio": dict(
        kind="visual_inertial", format="eqvio_csv", files=["gtsam_data/eqvio_processed_30s.csv"],
        title="30 s of real EuRoC V1_01_easy: IMU at 200 Hz and tracked image features at 20 Hz "
              "(gtsam's EqVIOFilterExample replay file)",
        licence=LIC_GTSAM, counts=dict(imu=6001, frames=601, features=13316, tracks=307),
        notes="Features are undistorted normalised coordinates with a track id; metadata T_ci_* is "
              "imu_T_camera (EuRoC cam0 T_BS). Read by slamkit.data.formats.eqvio_csv; scored against "
              "v101-gt beside v101-openvins (slamkit.experiments.visual_inertial)."),
    "kitti00-gt": dict(
        kind="trajectory", format="kitti",
        files=["reference_trajectories/KITTI_00_gt.txt", "reference_trajectories/KITTI_00_gt_times.txt"],
        title="KITTI odometry 00 ground truth (4,541 poses) with frame times", licence=LIC_EVO_DATA,
        counts=dict(poses=4541)),
    "kitti00-orbslam": dict(
        kind="trajectory", format="kitti", files=["reference_trajectories/KITTI_00_ORB.txt"],
        title="ORB-SLAM's estimate of KITTI odometry 00", licence=LIC_EVO_DATA,
        refs=[("ape_rmse_m", 1.30345, "ape_translation_se3", True,
               "evo's stored result (test/data): APE translation RMSE after SE(3) Umeyama alignment"),
              ("rpe_rmse_10m", 0.22626, "rpe_translation_10m", True,
               "evo's stored result (test/data): RPE translation RMSE over 10 m")]),
    "v101-gt": dict(
        kind="trajectory", format="tum", files=["reference_trajectories/V101_gt.txt"],
        title="EuRoC V1_01_easy ground truth at camera times", licence=LIC_EVO_DATA),
    "v101-openvins": dict(
        kind="trajectory", format="tum", files=["reference_trajectories/V101_openvins.txt"],
        title="OpenVINS estimate of EuRoC V1_01_easy", licence=LIC_EVO_DATA),
    "fr1-xyz-gt": dict(
        kind="trajectory", format="tum", files=["reference_trajectories/freiburg1_xyz-groundtruth.txt"],
        title="TUM RGB-D fr1/xyz ground truth", licence=LIC_EVO_DATA),
    "fr1-xyz-rgbdslam": dict(
        kind="trajectory", format="tum", files=["reference_trajectories/freiburg1_xyz-rgbdslam.txt"],
        title="RGBD-SLAM's estimate of TUM RGB-D fr1/xyz", licence=LIC_EVO_DATA),
    "willow": dict(
        kind="grid_map", format="ros_map",
        files=["maps_ros/willow-2010-02-18-0.10.yaml", "maps_ros/willow-2010-02-18-0.10.pgm"],
        title="Willow Garage office, ROS map_server map built from real laser data (566 x 608 at 0.1 m)",
        licence=LIC_WILLOW, counts=dict(width=566, height=608)),
}
