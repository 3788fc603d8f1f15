"""Flight control: the commander's target -> reference -> motor commands (PX4 mc_pos_control + mc_att_control)."""
