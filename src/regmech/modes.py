"""Mode codes of variable-structure devices (friction and loss elements).

One integer per device selects the branch of its universal equation
(REFERENCES.md [003], MSL PartialFriction); the codes are shared by the
components that state the laws, the compiled rows that evaluate them and
the hybrid layer that switches them, so they live in the core.
"""

BACKWARD, STUCK, FORWARD, FREE, HELD = -1, 0, 1, 2, 3

MODE_NAMES = {BACKWARD: "Backward", STUCK: "Stuck", FORWARD: "Forward", FREE: "Free", HELD: "Held"}
