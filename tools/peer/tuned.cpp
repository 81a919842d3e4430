// The race's "tuned" peer: ContinuumRobotExamples' algorithm (RK4 shooting
// on the base wrench, Levenberg-Marquardt with a forward-difference Jacobian
// and its damping schedule, from a zero guess) written with fixed-size Eigen
// types and no allocation in the loop. Output as teaching.cpp's. Built and
// run by tools/peer_race.py (needs Eigen: Debian's libeigen3-dev).
#include <iostream>
#include <chrono>
#include <vector>
#include <algorithm>
#include <Eigen/Dense>
using namespace Eigen;
typedef Matrix<double,6,1> V6; typedef Matrix<double,6,6> M6;
static double ALPHA = 3.0;
const double L = 1.0;
struct St { Vector3d p; Matrix3d R; Vector3d n, m; };
static inline Matrix3d hat(const Vector3d& u){ Matrix3d h; h << 0,-u(2),u(1), u(2),0,-u(0), -u(1),u(0),0; return h; }
static inline St ode(const St& y){
    St d;
    Vector3d v = 1e-10*(y.R.transpose()*y.n) + Vector3d::UnitZ();
    Vector3d u = y.R.transpose()*y.m;   // Kbt = I
    d.p = y.R*v; d.R = y.R*hat(u); d.n.setZero(); d.m = -d.p.cross(y.n);
    return d;
}
static inline St axpy(const St& y, const St& k, double h){ St r; r.p=y.p+h*k.p; r.R=y.R+h*k.R; r.n=y.n+h*k.n; r.m=y.m+h*k.m; return r; }
template<int N> struct Shot {
    static Vector3d P[N];
    static V6 f(const V6& g){
        St y; y.p.setZero(); y.R.setIdentity(); y.n = g.head<3>(); y.m = g.tail<3>();
        double ds = L/(N-1); P[0] = y.p;
        for(int i = 0; i < N-1; i++){
            St k0 = ode(y), k1 = ode(axpy(y,k0,ds/2)), k2 = ode(axpy(y,k1,ds/2)), k3 = ode(axpy(y,k2,ds));
            y.p += ds/6*(k0.p+2*(k1.p+k2.p)+k3.p); y.R += ds/6*(k0.R+2*(k1.R+k2.R)+k3.R);
            y.n += ds/6*(k0.n+2*(k1.n+k2.n)+k3.n); y.m += ds/6*(k0.m+2*(k1.m+k2.m)+k3.m);
            P[i+1] = y.p;
        }
        V6 e; e << y.n - Vector3d(0,-ALPHA,0), y.m; return e;
    }
    static V6 lm(V6 y, double sos_tol){
        V6 r = f(y); double E = r.squaredNorm(); double damp = 1e-2;
        for(int it = 0; it < 500 && E > sos_tol; it++){
            M6 J;
            for(int c = 0; c < 6; c++){ double h = std::max(1e-8*std::abs(y(c)), 1e-12); V6 yp = y; yp(c) += h; J.col(c) = (f(yp)-r)/h; }
            M6 B = J.transpose()*J; V6 rhs = -J.transpose()*r;
            damp *= 0.5;
            while(true){
                M6 A = B; A.diagonal().array() += damp;
                V6 pc = A.llt().solve(rhs); V6 rc = f(y+pc); double Ec = rc.squaredNorm();
                if(!rc.hasNaN() && Ec < E){ y += pc; r = rc; E = Ec; break; }
                damp /= 0.5; if(damp > 1e12) return y;
            }
        }
        return y;
    }
};
template<int N> Vector3d Shot<N>::P[N];
template<int N> void run(double tol){
    std::vector<double> times; V6 sol;
    for(int k = 0; k < 2000; k++){
        auto t0 = std::chrono::steady_clock::now();
        sol = Shot<N>::lm(V6::Zero(), tol);
        auto t1 = std::chrono::steady_clock::now();
        times.push_back(std::chrono::duration<double, std::micro>(t1-t0).count());
    }
    std::sort(times.begin(), times.end()); Shot<N>::f(sol);
    std::cout << N << " " << times[times.size()/2];
    for(int j = 0; j < N; j++) std::cout << " " << Shot<N>::P[j](0) << " " << Shot<N>::P[j](1) << " " << Shot<N>::P[j](2);
    std::cout << "\n";
}
int main(int argc, char** argv){
    ALPHA = atof(argv[1]); double tol = argc > 2 ? atof(argv[2]) : 1e-12; std::cout.precision(17);
    run<5>(tol); run<6>(tol); run<9>(tol); run<11>(tol); run<17>(tol); run<21>(tol); run<33>(tol); run<41>(tol); run<65>(tol); run<81>(tol); run<129>(tol);
}
