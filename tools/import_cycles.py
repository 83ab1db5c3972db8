#!/usr/bin/env python3
"""The library's file-level import graph (crate:: and super:: paths outside comments and test
modules; src/main.rs left out) and its cycles (strongly connected components). Exits 1 when
there is one. `-v` prints every file's imports. Used by .ci/run."""
import os,re,sys
root=sys.argv[1] if len(sys.argv)>1 else 'src'
files={}
for d,_,fs in os.walk(root):
    for f in fs:
        if f.endswith('.rs') and f!='main.rs': files[os.path.join(d,f)]=open(os.path.join(d,f)).read()
def modpath(p):
    r=os.path.relpath(p,root)[:-3].split('/')
    if r[-1] in ('mod','lib','main'): r=r[:-1]
    return r
mods={tuple(modpath(p)):p for p in files if not p.endswith('main.rs')}
def resolve(path):
    # longest prefix that is a module file
    for k in range(len(path),-1,-1):
        if tuple(path[:k]) in mods: return mods[tuple(path[:k])]
edges={p:set() for p in files if not p.endswith('main.rs')}
for p,s in files.items():
    s=re.sub(r'#\[cfg\(test\)\]\s*mod tests \{.*','',s,flags=re.S)
    s=re.sub(r'//[^\n]*','',s)
    me=modpath(p)
    for m in re.finditer(r'\b(crate|super)((?:::\w+)+)',s):
        parts=m.group(2).split('::')[1:]
        if m.group(1)=='crate': full=parts
        else:
            base=me[:-1] if not p.endswith('mod.rs') else me[:-1]
            full=base+parts
        t=resolve(full)
        if t and t!=p and t in edges: edges[p].add(t)
    # use { a, b } groups under crate::x::{...}
    for m in re.finditer(r'crate::((?:\w+::)*)\{([^}]*)\}',s):
        pre=m.group(1).strip(':').split('::') if m.group(1) else []
        for item in m.group(2).split(','):
            item=item.strip().split('::')[0].strip()
            if not item or item=='self': continue
            t=resolve(pre+[item])
            if t and t!=p and t in edges: edges[p].add(t)
# ignore edges from a parent mod.rs to its children (declarations) and lib.rs
idx={};low={};st=[];on=set();sccs=[];c=[0]
sys.setrecursionlimit(10000)
def sc(v):
    idx[v]=low[v]=c[0];c[0]+=1;st.append(v);on.add(v)
    for w in edges[v]:
        if w not in idx: sc(w);low[v]=min(low[v],low[w])
        elif w in on: low[v]=min(low[v],idx[w])
    if low[v]==idx[v]:
        comp=[]
        while True:
            w=st.pop();on.discard(w);comp.append(w)
            if w==v:break
        sccs.append(comp)
for v in files:
    if v not in idx: sc(v)
cyc=[s for s in sccs if len(s)>1]
for s in cyc: print('CYCLE:',sorted(os.path.relpath(x,root) for x in s))
if '-v' in sys.argv:
    for p in sorted(edges): print(os.path.relpath(p,root),'->',sorted(os.path.relpath(x,root) for x in edges[p]))
print(len(cyc),'cycles')
sys.exit(1 if cyc else 0)
