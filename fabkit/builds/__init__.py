"""How a build goes together and how loose it is: joint play as freedom, bars as elastic members.

The rigid kinematic model (:mod:`fabkit.kinematics`) gives every bar its length exactly. A real
build has two more things, and this package models them, each only where it changes the answer
(../DESIGN.md, levels of model 5 and 6):

Play (level 5)
    A pin in a hole wider than it lets the bar's end sit anywhere in the hole: the distance
    between the two pins of bar ``e`` may be anything in ``[L_e - c_e, L_e + c_e]``, with the
    axial room ``c_e`` the sum of the two holes' radial clearances (exactly, not only to first
    order). A build whose bars have length errors ``δL`` goes together when some lengths within
    that room close every loop. To first order, with the states of self-stress ``W`` (the left
    null space of the rigidity matrix), when some ``s`` with ``|s_e| <= c_e`` has
    ``Wᵀ(δL + s) = 0`` — for one state ``w``, when ``|w·δL| <= Σ|w_e| c_e``
    (:mod:`.closure`); confirmed on the nonlinear network by bounded least squares
    (:mod:`.assembly`). With the drive held, the play still lets a port wander: its **slop**, the
    largest change of its distance over the play (first order, a linear program; :mod:`.slop`).

Give (level 6)
    Where the play is too small, the bars are springs ``k_e = E A / L`` (the process's material
    and section, :mod:`.materials`) with the play as a dead band: the least-energy assembly, the
    axial stress of every bar ``σ = E ε`` against the material's allowable stress, and the force
    on the worst joint (:mod:`.assembly`).

A network without self-stress assembles with any lengths and pays for none of this.
"""
