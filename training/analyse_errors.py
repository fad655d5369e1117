"""Where the float network's centre errors come from on a dataset (numpy;
docs/NN.md): detections more than 40 px off the label ("gross") against
the rest, by the label's distance.

    python3 training/analyse_errors.py DIR
"""

import os
import sys, numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import netdef, export, int8_ref, evaluate
small, labels = netdef.load_dataset(sys.argv[1])
ck = export.load_checkpoint(os.path.join(export.HERE, 'checkpoint.npz'))
head = int8_ref.float_forward(ck, netdef.to_int8(small).astype(np.float64) / 128)
pred = evaluate.decode_float(head)
gross, fine, miss, missd = [], [], [], []
for p, r in zip(pred, labels):
    if not r['visible']: continue
    if not p[0]: missd.append(r['distance_m']); continue
    e = np.hypot(p[1]-r['u'], p[2]-r['v'])
    (gross if e > 40 else fine).append((r['distance_m'], e, abs(p[3]-r['distance_m'])))
g = np.array(gross); f = np.array(fine)
print('detected', len(gross)+len(fine), 'gross>40px', len(gross), 'share', len(gross)/(len(gross)+len(fine)))
print('label distance: gross median', np.median(g[:,0]), 'fine median', np.median(f[:,0]), 'missed median', np.median(missd))
print('gross with label > 6 m', np.mean(g[:,0] > 6), 'fine >6m', np.mean(f[:,0] > 6), 'missed > 6m', np.mean(np.array(missd) > 6))
print('mean err fine', f[:,1].mean(), 'median fine', np.median(f[:,1]))
print('predicted distance - label for gross (median, m)', np.median(g[:,2]))
