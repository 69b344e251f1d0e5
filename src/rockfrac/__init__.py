"""rockfrac: quasi-static finite element fracture of rock.

Elasto-plastic (EP) and rigid-plastic (RP) cohesive surface elements and embedded
strong discontinuity elements, after Regueiro & Yu (ARMA 2010).
"""

__version__ = "0.1.0"
