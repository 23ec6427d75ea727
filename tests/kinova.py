"""The Kinova Gen2 (j2s6s200) of example-robot-data as tests describe it: a robot that is not shipped, whose URDF
fixes its fingers (docs/robots.md's worked example, with ``skip = []`` so that no self-collision pairs are sampled)."""

KINOVA = """[robot]
urdf = "{urdf}"
[base]
kind = "fixed"
[[arms]]
name = "arm"
joints = ["j2s6s200_joint_1", "j2s6s200_joint_2", "j2s6s200_joint_3", "j2s6s200_joint_4", "j2s6s200_joint_5",
          "j2s6s200_joint_6"]
tool_frame = "j2s6s200_end_effector"
approach = "+x"
closing = "y"
home = [4.80, 2.92, 1.00, 4.20, 1.44, 1.32]
[arms.gripper]
{joints}
fingers = ["j2s6s200_link_finger_tip_1", "j2s6s200_link_finger_tip_2"]
[self_collision]
skip = []
"""
KINOVA_URDF = "example-robot-data:kinova_description/robots/kinova.urdf"
KINOVA_FINGERS = "joints = { j2s6s200_joint_finger_1 = -1.0, j2s6s200_joint_finger_2 = -1.0 }"


def kinova(tmp_path, joints=KINOVA_FINGERS, urdf=KINOVA_URDF):
    path = tmp_path / "kinova.toml"
    path.write_text(KINOVA.format(urdf=urdf, joints=joints))
    return path
