#!/usr/bin/env python3
"""Cluster pairs of Trp-cage's grid for orderings of a column's atoms (issue 39, sitting
docs/data/sittings/kernel-2026-11-29-f.txt): z only (the grid's), slabs of k clusters with the
atoms with Lennard-Jones first, and LJ / non-LJ atoms cut into clusters apart. A model of
src/forces/clusters/grid.rs (columns of width (4/rho)^(1/3), clusters of four), brute force
over cluster pairs with the minimum image; "live" = an atom pair within 9 A, "inner" within
11 A; "with LJ" = the i-cluster (by the list's cyclic half rule) or both hold an LJ atom.

    python3 scripts/lj_cluster_pairs.py      # from the repository root, needs numpy
"""
import numpy as np
gro = open('systems/protein-amber/trpcage.gro').read().splitlines()[2:2+6920]
names = [(l[5:10].strip(), l[10:15].strip()) for l in gro]
# no LJ: water hydrogens, hydroxyl H (SER HG, THR HG1, TYR HH)
nolj = np.array([(r=='HOH' and a.startswith('H')) or (r=='SER' and a=='HG') or (r=='TYR' and a=='HH') or (r=='THR' and a=='HG1') for r,a in names])
lj = ~nolj
xyz = np.loadtxt('systems/protein-amber/trpcage-300K.xyz', skiprows=2, usecols=(1,2,3))
L = 42.0
x = xyz % L
n = len(x)
print('atoms', n, 'LJ', lj.sum())
rho = n / L**3
w = (4/rho)**(1/3); nc = int(L//w); w = L/nc
col = (np.minimum((x[:,0]//w).astype(int), nc-1))*nc + np.minimum((x[:,1]//w).astype(int), nc-1)

def clusters(mode, k=2):
    out = []
    for c in range(nc*nc):
        idx = np.where(col==c)[0]
        idx = idx[np.lexsort((idx, x[idx,2]))]
        if mode == 'z':
            groups = [idx]
        elif mode == 'sep':
            groups = [idx[lj[idx]], idx[~lj[idx]]]
        elif mode == 'slab':
            order = []
            for s in range(0, len(idx), 4*k):
                sl = idx[s:s+4*k]
                order += list(sl[lj[sl]]) + list(sl[~lj[sl]])
            groups = [np.array(order, int)]
        for g in groups:
            for s in range(0, len(g), 4):
                out.append(g[s:s+4])
    return out

def stats(cl, rin=11.0, rc=9.0):
    N = len(cl)
    P = np.full((N,4,3), 1e6); has = np.zeros(N, bool)
    for i,c in enumerate(cl):
        P[i,:len(c)] = x[c]; has[i] = lj[c].any()
    listed = live = live_ilj = live_both = 0
    for i in range(N):
        d = P[i][None,:,None,:] - P[i:][:,None,:,:]   # j>=i
        d -= L*np.round(d/L)
        r2 = (d**2).sum(-1).reshape(N-i,16)
        r2[0] = np.inf  # a cluster with itself left out (the same in every order)
        mn = r2.min(1)
        js = np.arange(i, N)
        inl = mn < rin**2; lv = mn < rc**2
        # orientation by cyclic half: i' is the one with 0<(cj-ci) mod N < N/2
        fwd = ((js - i) % N) < N/2
        ilj = np.where(fwd, has[i], has[js])
        listed += inl.sum(); live += lv.sum()
        live_ilj += (lv & ilj).sum(); live_both += (lv & has[i] & has[js]).sum()
    return N, listed, live, live_ilj, live_both, has.mean()

modes = [('z',0),('slab',2),('slab',3),('slab',4),('sep',0)]
for m,k in modes:
    cl = clusters(m,k)
    N, listed, live, ilj, both, frac = stats(cl)
    print(f'{m}{k}: clusters {N} LJclusters {frac:.3f} inner-listed {listed} live {live} live-iLJ {ilj} ({ilj/live:.2f}) live-bothLJ {both} ({both/live:.2f})', flush=True)
