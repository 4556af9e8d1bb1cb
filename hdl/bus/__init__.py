"""Bus front ends shared by the cores: an AXI4 slave in front of a simple word back end."""
