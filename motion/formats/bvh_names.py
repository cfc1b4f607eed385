"""Built-in maps from the joint names BVH writers use to the project skeletons' joints.

Per project skeleton, one map per naming style (CMU, Mixamo, LAFAN1, Bandai-Namco, SMPL as
smpl2bvh writes it, HumanML3D as MoMask's ``joints2bvh`` does); :func:`motion.formats.
bvh.joint_map` uses the one that leaves fewest joints unmapped. End Sites are named after
their joint (``Head`` -> ``Head_End``).
"""

END_SUFFIX = "_End"

# Names are compared ignoring case and a namespace prefix ("mixamorig:Hips" is "Hips").
_LEGS_H36M = {"RHip": "RightUpLeg", "RKnee": "RightLeg", "RFoot": "RightFoot",
              "LHip": "LeftUpLeg", "LKnee": "LeftLeg", "LFoot": "LeftFoot"}
_ARMS_H36M = {"LShoulder": "LeftArm", "LElbow": "LeftForeArm", "LWrist": "LeftHand",
              "RShoulder": "RightArm", "RElbow": "RightForeArm", "RWrist": "RightHand"}
_LIMBS_SMPL = {"left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "left_knee": "LeftLeg",
               "right_knee": "RightLeg", "left_ankle": "LeftFoot", "right_ankle": "RightFoot",
               "left_foot": "LeftToeBase", "right_foot": "RightToeBase",
               "left_collar": "LeftShoulder", "right_collar": "RightShoulder",
               "left_shoulder": "LeftArm", "right_shoulder": "RightArm",
               "left_elbow": "LeftForeArm", "right_elbow": "RightForeArm",
               "left_wrist": "LeftHand", "right_wrist": "RightHand"}
_SMPL_NAMES = ("pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee",
               "spine2", "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot",
               "neck", "left_collar", "right_collar", "head", "left_shoulder",
               "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
               "left_hand", "right_hand")
_SIDES = (("left", "Left"), ("right", "Right"))
# MoMask's joints2bvh (HumanML3D's 22 joints), and the 24 of its smpl2bvh.
_HUMANML3D = {
    "pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2",
    "neck": "Neck", "head": "Head",
    **{f"{side}_{joint}": f"{Side}{bvh}" for side, Side in _SIDES for joint, bvh in (
        ("hip", "UpLeg"), ("knee", "Leg"), ("ankle", "Foot"), ("foot", "Toe"),
        ("collar", "Shoulder"), ("shoulder", "Arm"), ("elbow", "ForeArm"), ("wrist", "Hand"),
        ("hand", "Thumb"))},
}
# SMPL names as smpl2bvh writes them: Pelvis, Left_hip, ... (compared ignoring case).
_SMPL_STYLE = {name: name for name in _SMPL_NAMES}
_SMPL_PALM = {**_SMPL_STYLE, "left_hand": "Left_palm", "right_hand": "Right_palm"}
# LAFAN1 (Ubisoft) names its 22 joints as MoMask does, without fingers: a hand's End Site
# stands for SMPL's hand joint.
_LAFAN1 = {**_HUMANML3D, "left_hand": "LeftHand" + END_SUFFIX,
           "right_hand": "RightHand" + END_SUFFIX}
# The Bandai-Namco motion dataset: Hips, Spine, Chest, Neck, Head and <Part>_L/_R, under a
# static joint_Root. Its spine has two joints below the neck, as CMU's: Neck stands in
# for SMPL's spine3 and Head for its neck.
_BANDAI = {"pelvis": "Hips", "spine1": "Spine", "spine2": "Chest", "spine3": "Neck",
           "neck": "Head", "head": "Head" + END_SUFFIX,
           **{f"{side}_{joint}": f"{bvh}_{side[0].upper()}" for side, _ in _SIDES
              for joint, bvh in (("hip", "UpperLeg"), ("knee", "LowerLeg"), ("ankle", "Foot"),
                                 ("foot", "Toes"), ("collar", "Shoulder"),
                                 ("shoulder", "UpperArm"), ("elbow", "LowerArm"),
                                 ("wrist", "Hand"))},
           "left_hand": "Hand_L" + END_SUFFIX, "right_hand": "Hand_R" + END_SUFFIX}
JOINT_MAPS: dict[str, dict[str, dict[str, str]]] = {
    "h36m17": {
        # CMU's Neck starts where Spine1 ends, between the shoulders; Head is the skull's
        # base and its End Site the top of the head.
        "cmu": {"Hip": "Hips", "Spine": "Spine", "Thorax": "Neck", "Neck/Nose": "Head",
                "Head": "Head" + END_SUFFIX, **_LEGS_H36M, **_ARMS_H36M},
        "mixamo": {"Hip": "Hips", "Spine": "Spine1", "Thorax": "Neck", "Neck/Nose": "Head",
                   "Head": "HeadTop_End", **_LEGS_H36M, **_ARMS_H36M},
        "lafan1": {"Hip": "Hips", "Spine": "Spine1", "Thorax": "Neck", "Neck/Nose": "Head",
                   "Head": "Head" + END_SUFFIX, **_LEGS_H36M, **_ARMS_H36M},
        "bandai": {"Hip": "Hips", "Spine": "Spine", "Thorax": "Neck", "Neck/Nose": "Head",
                   "Head": "Head" + END_SUFFIX,
                   **{f"{s}{joint}": f"{bvh}_{s}" for s in "LR" for joint, bvh in (
                       ("Hip", "UpperLeg"), ("Knee", "LowerLeg"), ("Foot", "Foot"),
                       ("Shoulder", "UpperArm"), ("Elbow", "LowerArm"), ("Wrist", "Hand"))}},
    },
    "humanact12": {
        # CMU's spine has two joints below the neck; its Neck1 (mid-neck) stands in for
        # SMPL's spine3 so that no bone has zero length.
        "cmu": {"pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Neck1",
                "neck": "Head", "head": "Head" + END_SUFFIX, "left_hand": "LeftHandIndex1",
                "right_hand": "RightHandIndex1", **_LIMBS_SMPL},
        "mixamo": {"pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2",
                   "neck": "Neck", "head": "Head", "left_hand": "LeftHandMiddle1",
                   "right_hand": "RightHandMiddle1", **_LIMBS_SMPL},
        "smpl": _SMPL_STYLE,
        "smpl_palm": _SMPL_PALM,
        "humanml3d": _HUMANML3D,
        "lafan1": _LAFAN1,
        "bandai": _BANDAI,
    },
}
# smpl24 has humanact12's joints; smpl22 its first 22 (the maps' extra joints are unused).
JOINT_MAPS["smpl24"] = JOINT_MAPS["humanact12"]
JOINT_MAPS["smpl22"] = JOINT_MAPS["humanact12"]
