"""Element groups: bulk solids and cohesive surfaces. Each owns its dofs and its state arrays."""
