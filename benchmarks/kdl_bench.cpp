// Times KDL's ChainHdSolver_Vereshchagin on a chain given on stdin (ifc-spg dynamics bench).
//
// Built by benchmarks/kdl.py at run time (g++ -O2 against liborocos-kdl-dev) and fed
// the same chain, constraints and states as our solver. Input (whitespace-separated):
//   nseg nc nstates repeat
//   per segment: type (1 revolute, 2 prismatic) axis(3) rotor_inertia
//                f_tip R(9, row-major) p(3)  mass cog(3) Ixx Iyy Izz Ixy Ixz Iyz
//                (the inertia in the segment's tip frame, about the cog)
//   root_acc(6) alpha(6 x nc, row-major) beta(nc)
//   per state: q(nj) qd(nj) tau(nj)
// Output: one line "qdd v1 ... vnj" per state (first call), then one line
// "ns t1 t2 ..." with the wall time of every timed call in nanoseconds.
#include <chrono>
#include <cstdio>
#include <iostream>
#include <vector>

#include <kdl/chain.hpp>
#include <kdl/chainhdsolver_vereshchagin.hpp>
#include <kdl/frames.hpp>
#include <kdl/jacobian.hpp>
#include <kdl/jntarray.hpp>

int main() {
    unsigned nseg, nc, nstates, repeat;
    if (!(std::cin >> nseg >> nc >> nstates >> repeat)) {
        std::cerr << "kdl_bench: bad header\n";
        return 2;
    }
    KDL::Chain chain;
    for (unsigned s = 0; s < nseg; s++) {
        int type;
        double ax[3], rotor, R[9], p[3], m, c[3], I[6];
        std::cin >> type >> ax[0] >> ax[1] >> ax[2] >> rotor;
        for (double &v : R) std::cin >> v;
        for (double &v : p) std::cin >> v;
        std::cin >> m >> c[0] >> c[1] >> c[2];
        for (double &v : I) std::cin >> v;
        KDL::Joint joint = type == 0 ? KDL::Joint(KDL::Joint::Fixed)
                                     : KDL::Joint(KDL::Vector(0, 0, 0),
                                                  KDL::Vector(ax[0], ax[1], ax[2]),
                                                  type == 1 ? KDL::Joint::RotAxis
                                                            : KDL::Joint::TransAxis,
                                                  1.0, 0.0, rotor);
        KDL::Frame tip(KDL::Rotation(R[0], R[1], R[2], R[3], R[4], R[5], R[6], R[7], R[8]),
                       KDL::Vector(p[0], p[1], p[2]));
        KDL::RigidBodyInertia inertia(
            m, KDL::Vector(c[0], c[1], c[2]),
            KDL::RotationalInertia(I[0], I[1], I[2], I[3], I[4], I[5]));
        chain.addSegment(KDL::Segment(joint, tip, inertia));
    }
    double a0[6];
    for (double &v : a0) std::cin >> v;
    const unsigned nj = chain.getNrOfJoints();
    KDL::Jacobian alpha(nc);
    KDL::JntArray beta(nc);
    std::vector<double> al(6 * nc);
    for (double &v : al) std::cin >> v;
    for (unsigned r = 0; r < 6; r++)
        for (unsigned c = 0; c < nc; c++) alpha(r, c) = al[r * nc + c];
    for (unsigned c = 0; c < nc; c++) std::cin >> beta(c);
    std::vector<KDL::JntArray> qs, qds, taus;
    for (unsigned k = 0; k < nstates; k++) {
        KDL::JntArray q(nj), qd(nj), tau(nj);
        for (unsigned j = 0; j < nj; j++) std::cin >> q(j);
        for (unsigned j = 0; j < nj; j++) std::cin >> qd(j);
        for (unsigned j = 0; j < nj; j++) std::cin >> tau(j);
        qs.push_back(q);
        qds.push_back(qd);
        taus.push_back(tau);
    }
    if (!std::cin) {
        std::cerr << "kdl_bench: input ended early\n";
        return 2;
    }
    KDL::Twist root(KDL::Vector(a0[0], a0[1], a0[2]), KDL::Vector(a0[3], a0[4], a0[5]));
    KDL::ChainHdSolver_Vereshchagin solver(chain, root, nc);
    KDL::Wrenches fext(chain.getNrOfSegments(), KDL::Wrench::Zero());
    KDL::JntArray qdd(nj), ctau(nj);
    for (unsigned k = 0; k < nstates; k++) {
        int err = solver.CartToJnt(qs[k], qds[k], qdd, alpha, beta, fext, taus[k], ctau);
        if (err < 0) {
            std::cerr << "kdl_bench: CartToJnt failed with " << err << "\n";
            return 3;
        }
        std::printf("qdd");
        for (unsigned j = 0; j < nj; j++) std::printf(" %.17g", qdd(j));
        std::printf("\n");
    }
    std::vector<long long> ns;
    ns.reserve(static_cast<size_t>(repeat) * nstates);
    for (unsigned r = 0; r < repeat; r++) {
        for (unsigned k = 0; k < nstates; k++) {
            auto t0 = std::chrono::steady_clock::now();
            solver.CartToJnt(qs[k], qds[k], qdd, alpha, beta, fext, taus[k], ctau);
            auto t1 = std::chrono::steady_clock::now();
            ns.push_back(std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count());
        }
    }
    std::printf("ns");
    for (long long t : ns) std::printf(" %lld", t);
    std::printf("\n");
    return 0;
}
